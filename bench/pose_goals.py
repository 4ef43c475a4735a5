"""The MBM Panda problems with pose goals, through the REST API, checked independently.

Each MotionBenchMaker Panda problem (`../shared/data/mbm-panda`, mbm_problems) is asked with its
goal turned into the pose of `panda_hand` at the goal state (yourdfpy's forward kinematics of
the shipped URDF), within a 5 mm sphere and 0.05 rad about each axis, as a MoveIt pick request
gives it (`goal_pose`, native form):

- first pass, `lookup: false`, fallback with --budget s: solved, the server's time, and the time
  spent finding the goal state (`timings_ms.pose_goal`: IK, `ik_ms`);
- replay: the pose moved by 1–3 cm in a random direction, the lookup on: answered from the
  cache (`replay_hit_rate`), of which with a cached end that reaches the pose as it is
  (`replay_as_is_share`), and the server's time of a hit (`hit_server_ms_median`); beside it,
  in the same run, the same path asked with a joint goal as bench/mbm.py's replays ask it
  (`joint_hit_server_ms_median`; before the pose replay for odd problems, after it for even
  ones) and the ratio of the two medians (`hit_vs_joint_hit`).
  As bench/mbm.py draws its moved states within the limits and free, a moved pose is drawn
  again (up to 20 times) until a free state reaches it: an independent IK (`LineIk`, from
  the cached end, then from REACH_SEEDS random states) finds one within the limits that the
  dense check passes. A pose that puts the fingers inside a can, or past the arm's reach,
  is no request a cache or planner can answer (`replay_redraws` counts them; a problem with
  no reachable draw is left out, `replays_unreachable`).
  A reachable pose may still have no free state near the cached end (a joint at its limit,
  the arm blocked on the way): no cache can serve it. Each replay is judged without the
  service (`cartesian_filter.line_witness`: an independent IK path from the cached end along
  the straight line to the moved pose, the whole arm dense-checked along it); it is servable
  when that path is clear and ends within the service's default lookup threshold (0.2 rad on
  every joint) of the cached end. `replay_servable_hit_rate` is the hit rate over servable
  replays; the others are counted by reason (`replays_unservable`), and a hit among them is a
  bonus. `replay_solved_rate` is the share of replays the service answered (from the cache,
  repaired or planned within --budget s), and `replay_hit_rate_of_solved` the hit rate among
  those; `replay_answers` counts the answers by source and servability ("failed": none).

Every returned path is dense-checked as in bench/mbm.py (mbm_check: meshes, self-collision, the
scene's allowed pairs), and its last state's hand pose is checked against the pose asked, with
yourdfpy (`pose_errors`: out of tolerance). Prints a table and ends with one JSON line.

With `--cartesian`, straight 10 cm approach and retreat moves of the hand from each goal state
instead (`pose_cartesian`: `cartesian_success_rate`, `cartesian_ms_median`,
`cartesian_hit_rate`).

    python bench/pose_goals.py [--smoke] [--cartesian] [--per-family N] [--budget S] [--seed N]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import yourdfpy
from rich.console import Console
from rich.table import Table
from scipy.spatial.transform import Rotation

import pose_cartesian
from cartesian_filter import LineIk, line_witness
from harness.mbm_panda import register_panda
from harness.report import print_checked
from harness.service import running_service
from mbm_check import SceneChecker, check_path, panda_description
from mbm_problems import (
    ARM_JOINTS,
    DEFAULT_DATA,
    FAMILIES,
    allowed_pairs,
    clamp,
    load_problems,
    scene_objects,
    unpacked,
)
from mbm_tally import Tally, percentile
from trajcache_client import NO_RETRY, APIError, Client

LINK = "panda_hand"
POSITION_TOLERANCE = 0.005  # m: a 5 mm sphere
ORIENTATION_TOLERANCE = 0.05  # rad
MOVE_M = (0.01, 0.03)
LOOKUP_THRESHOLD = 0.2  # rad: the service's default, on every joint
REACH_SEEDS = 40  # random IK seeds that judge a moved pose reachable
JOINT_NOISE = 0.02  # rad per joint, of a joint-goal replay's start and goal (as bench/mbm.py)
SMOKE_PER_FAMILY = 2


class HandPose:
    """The hand's pose by yourdfpy, from the shipped URDF (no meshes needed)."""

    def __init__(self, robot_dir: Path) -> None:
        self.urdf = yourdfpy.URDF.load(str(robot_dir / "panda.urdf"), load_meshes=False,
                                       build_collision_scene_graph=False)  # fmt: skip

    def of(self, state: np.ndarray) -> np.ndarray:
        self.urdf.update_cfg(dict(zip(ARM_JOINTS, state.tolist(), strict=True)))
        return np.asarray(self.urdf.get_transform(LINK, self.urdf.base_link))

    def goal(self, state: np.ndarray, shift: np.ndarray | None = None) -> dict[str, Any]:
        pose = self.of(state)
        position = pose[:3, 3] + (0.0 if shift is None else shift)
        return {"link": LINK, "position": position.tolist(),
                "orientation": Rotation.from_matrix(pose[:3, :3]).as_quat().tolist(),
                "position_tolerance": POSITION_TOLERANCE,
                "orientation_tolerance": ORIENTATION_TOLERANCE}  # fmt: skip

    def error(self, state: np.ndarray, goal: dict[str, Any]) -> bool:
        """Whether the hand at `state` is out of the goal's tolerances."""
        pose = self.of(state)
        gap = np.linalg.norm(pose[:3, 3] - goal["position"])
        turn = Rotation.from_matrix(pose[:3, :3]).inv() * Rotation.from_quat(goal["orientation"])
        return bool(gap > POSITION_TOLERANCE + 1e-9 or turn.magnitude() > ORIENTATION_TOLERANCE)


class PoseRun:
    """The problems through a running service, with tallies of what came back."""

    def __init__(self, client: Client, args: argparse.Namespace) -> None:
        self.client, self.args = client, args
        robot_dir = args.data / "robot"
        self.hand = HandPose(robot_dir)
        self.checker = SceneChecker(panda_description(robot_dir))
        self.ik = LineIk(self.checker, LINK)
        self.model_id = register_panda(client, robot_dir).model_id
        self.counts: Counter[str] = Counter()
        self.times: dict[str, list[float]] = {"plan": [], "ik": [], "hit": [], "joint_hit": []}
        self.phases: dict[str, list[dict[str, float]]] = {"hit": [], "joint_hit": []}

    def ask(
        self, robot_id: str, start: np.ndarray, goal: dict[str, Any], lookup: bool
    ) -> dict[str, Any] | None:
        options = {"fallback": True, "budget_s": self.args.budget, "lookup": lookup}
        try:
            answer = self.client.plan(robot_id, start.tolist(), None, options, goal_pose=goal)
            return answer.model_dump()
        except APIError as exc:
            self.counts["http_5xx" if exc.status_code >= 500 else "http_4xx"] += 1
            return None

    def check(self, tally: Tally, answer: dict[str, Any], start: np.ndarray, goal: Any) -> None:
        states = np.asarray(answer["states"], dtype=float)
        check_path(tally, self.checker, states, (start, states[-1]), "pose")
        self.counts["pose_errors"] += self.hand.error(states[-1], goal)

    def problem(self, tally: Tally, problem: Any) -> None:
        robot_id = f"pose-{problem.label}"
        lower, upper = self.checker.lower, self.checker.upper
        start, _ = clamp(problem.start, lower, upper)
        goal_state, _ = clamp(problem.goal, lower, upper)
        self.client.put_robot(robot_id, self.model_id)
        self.client.put_scene(robot_id, problem.scene_text, media_type="application/yaml")
        self.checker.set_scene(scene_objects(problem.scene), allowed_pairs(problem.scene))
        tally.problems += 1
        goal = self.hand.goal(goal_state)
        answer = self.ask(robot_id, start, goal, lookup=False)
        if answer is None or answer["status"] != "success":
            tally.notes[str(answer and answer["message"])[:100]] += 1
            return
        tally.solved += 1
        self.times["plan"].append(answer["timings_ms"]["total"])
        self.times["ik"].append(answer["timings_ms"].get("pose_goal", 0.0))
        self.check(tally, answer, start, goal)
        rng = np.random.default_rng([self.args.seed, FAMILIES.index(problem.family), problem.index])
        cached_end = np.asarray(answer["states"][-1], dtype=float)
        drawn = self.draw_move(goal_state, cached_end, rng)
        if drawn is None:
            self.counts["replays_unreachable"] += 1
            return
        moved, unservable = drawn
        tally.counts["replays"] += 1
        tally.counts[f"unservable:{unservable}" if unservable else "servable"] += 1
        ends = (start, np.asarray(answer["states"][-1], dtype=float))
        if problem.index % 2:  # before the pose replay for odd problems, after it for even
            self.joint_replay(tally, robot_id, ends, rng)
        again = self.ask(robot_id, start, moved, lookup=True)
        if not problem.index % 2:
            self.joint_replay(tally, robot_id, ends, rng)
        if again is None or again["status"] != "success":
            self.counts[f"replay_answer:failed:{unservable or 'servable'}"] += 1
            self.miss(problem, unservable, again)
            return
        if again["source"] != "cache":
            self.miss(problem, unservable, again)
        self.counts[f"replay_answer:{again['source']}:{unservable or 'servable'}"] += 1
        tally.counts["replay_solved"] += 1
        self.check(tally, again, start, moved)
        if again["source"] == "cache":
            tally.counts["replay_hits"] += 1
            tally.counts["servable_hits"] += not unservable
            self.counts["as_is"] += again["goal_found_by"] == "cached"
            self.times["hit"].append(again["timings_ms"]["total"])
            self.phases["hit"].append(again["timings_ms"])

    def miss(self, problem: Any, unservable: str, answer: dict[str, Any] | None) -> None:
        """A replay not answered from the cache, written to --misses (one JSON line each)."""
        if self.args.misses is None:
            return
        record = {"family": problem.family, "index": problem.index, "unservable": unservable}
        if answer is not None:
            keys = ("status", "source", "message", "candidates_tried", "rejected")
            record |= {key: answer.get(key) for key in keys}
        with self.args.misses.open("a") as out:
            out.write(json.dumps(record) + "\n")

    def joint_replay(
        self, tally: Tally, robot_id: str, ends: tuple[np.ndarray, np.ndarray], rng: Any
    ) -> None:
        """The path asked again with a joint goal, as bench/mbm.py's replays ask it (start and
        goal moved by up to ±0.02 rad per joint, within the limits and free; no fallback): the
        server's time of a joint-goal hit, in the same run (`joint_hit_server_ms_median`)."""
        start, goal = (self.noisy(end, rng) for end in ends)
        if start is None or goal is None:
            return
        options = {"fallback": False, "lookup": True}
        try:
            answer = self.client.plan(robot_id, start.tolist(), goal.tolist(), options).model_dump()
        except APIError as exc:
            self.counts["http_5xx" if exc.status_code >= 500 else "http_4xx"] += 1
            return
        if answer["status"] == "success":
            states = np.asarray(answer["states"], dtype=float)
            check_path(tally, self.checker, states, (start, goal), "joint replay")
        if answer["source"] == "cache":
            self.times["joint_hit"].append(answer["timings_ms"]["total"])
            self.phases["joint_hit"].append(answer["timings_ms"])

    def noisy(self, state: np.ndarray, rng: Any) -> np.ndarray | None:
        """The state moved by up to ±JOINT_NOISE per joint, within the limits and free (as
        bench/mbm.py draws its replays); None after 20 draws."""
        lower, upper = self.checker.lower, self.checker.upper
        for _ in range(20):
            out = np.clip(state + rng.uniform(-JOINT_NOISE, JOINT_NOISE, len(state)), lower, upper)
            if self.checker.is_free(out):
                return out
        return None

    def draw_move(
        self, goal_state: np.ndarray, cached_end: np.ndarray, rng: Any
    ) -> tuple[dict[str, Any], str] | None:
        """The replay's pose (the goal's moved by MOVE_M in a random direction) and why no
        cached answer can serve it ("" when one can), redrawn until some free state reaches it
        (`reachable`, as bench/mbm.py draws its replays free); None after 20 draws."""
        for _ in range(20):
            direction = rng.normal(size=3)
            shift = direction / np.linalg.norm(direction) * rng.uniform(*MOVE_M)
            moved = self.hand.goal(goal_state, shift)
            unservable = self.unservable(cached_end, moved)
            if not unservable or self.reachable(cached_end, moved, rng):
                return moved, unservable
            self.counts["replay_redraws"] += 1
        return None

    def reachable(self, cached_end: np.ndarray, moved: dict[str, Any], rng: Any) -> bool:
        """Whether an independent IK (`LineIk`, from the cached end, then from REACH_SEEDS
        random states) finds a state within the limits that puts the hand at the pose and is
        free (dense mesh check)."""
        target = pin.SE3(Rotation.from_quat(moved["orientation"]).as_matrix(),
                         np.asarray(moved["position"], dtype=float))  # fmt: skip
        lower, upper = self.checker.lower, self.checker.upper
        seeds = [cached_end, *(rng.uniform(lower, upper) for _ in range(REACH_SEEDS))]
        for seed in seeds:
            state = self.ik.solve(seed, target)
            if state is not None and self.checker.is_free(state):
                return True
        return False

    def unservable(self, cached_end: np.ndarray, moved: dict[str, Any]) -> str:
        """Why no cached answer can reach the moved pose from the cached end (module
        docstring), or "" when one can."""
        shift = np.asarray(moved["position"]) - self.hand.of(cached_end)[:3, 3]
        reason, states = line_witness(self.ik, cached_end, shift)
        if not reason and np.abs(states[-1] - cached_end).max() >= LOOKUP_THRESHOLD:
            reason = "far_from_cache"
        return reason


def ratio(times: list[float], others: list[float]) -> float | None:
    """The ratio of the two medians (None without both)."""
    if not times or not others:
        return None
    return round(float(np.median(times) / np.median(others)), 2)


def phase_medians(timings: list[dict[str, float]]) -> dict[str, float | None]:
    """The median of each phase the answers' `timings_ms` name (a phase an answer lacks: 0)."""
    phases = sorted({phase for one in timings for phase in one})
    return {phase: percentile([one.get(phase, 0.0) for one in timings]) for phase in phases}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the mbm-panda folder")
    parser.add_argument("--per-family", type=int, help="problems per family (default all)")
    parser.add_argument("--budget", type=float, default=5.0, help="planning budget s")
    parser.add_argument("--seed", type=int, default=1, help="of the replays' shifts")
    parser.add_argument("--smoke", action="store_true", help=f"{SMOKE_PER_FAMILY} per family")
    parser.add_argument("--cartesian", action="store_true", help="Cartesian moves instead")
    parser.add_argument("--misses", type=Path, help="a file: one JSON line per replay missed")
    args = parser.parse_args(argv)
    if args.smoke and args.per_family is None:
        args.per_family, args.budget = SMOKE_PER_FAMILY, 2.0
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.cartesian:
        return pose_cartesian.main(args, PoseRun)
    began = time.perf_counter()
    problems = load_problems(unpacked(args.data), list(FAMILIES), args.per_family)
    tallies: dict[str, Tally] = {}
    with running_service() as base, Client(base, timeout=120, retry=NO_RETRY) as client:
        run = PoseRun(client, args)
        for problem in problems:
            run.problem(tallies.setdefault(problem.family, Tally(problem.family)), problem)
    counts = sum((t.counts for t in tallies.values()), run.counts)
    solved = sum(t.solved for t in tallies.values())
    problems_n = sum(t.problems for t in tallies.values())
    table = Table(title="MotionBenchMaker, Panda, pose goals (panda_hand, 5 mm, 0.05 rad)")
    for name in ("family", "problems", "solved", "replay hits"):
        table.add_column(name)
    for t in tallies.values():
        hits = (
            f"{t.counts['replay_hits']} of {t.counts['replays']} ({t.counts['servable']} servable)"
        )
        table.add_row(t.family, str(t.problems), str(t.solved), hits)
    Console(width=120).print(table)
    replays, hits, servable = counts["replays"], counts["replay_hits"], counts["servable"]
    unservable = {
        k.split(":", 1)[1]: n for k, n in sorted(counts.items()) if k.startswith("unservable:")
    }
    answers = {
        k.split(":", 1)[1]: n for k, n in sorted(counts.items()) if k.startswith("replay_answer:")
    }
    solved_replays = counts["replay_solved"]
    figures = {
        "problems": problems_n,
        "success_rate": round(solved / problems_n, 4) if problems_n else None,
        "plan_ms_median": percentile(run.times["plan"]),
        "ik_ms_median": percentile(run.times["ik"]),
        "replays": replays,
        "replay_redraws": counts["replay_redraws"],
        "replays_unreachable": counts["replays_unreachable"],
        "replay_hit_rate": round(hits / replays, 4) if replays else None,
        "replay_servable_hit_rate": (
            round(counts["servable_hits"] / servable, 4) if servable else None
        ),
        "replays_unservable": unservable,
        "replay_solved_rate": round(solved_replays / replays, 4) if replays else None,
        "replay_hit_rate_of_solved": (round(hits / solved_replays, 4) if solved_replays else None),
        "replay_answers": answers,
        "replay_as_is_share": round(counts["as_is"] / hits, 4) if hits else None,
        "hit_server_ms_median": percentile(run.times["hit"]),
        "joint_hit_server_ms_median": percentile(run.times["joint_hit"]),
        "hit_vs_joint_hit": ratio(run.times["hit"], run.times["joint_hit"]),
        "hit_phases_ms_median": phase_medians(run.phases["hit"]),
        "joint_hit_phases_ms_median": phase_medians(run.phases["joint_hit"]),
    }
    return print_checked(figures, counts, check="pose_errors", began=began, smoke=args.smoke)


if __name__ == "__main__":
    sys.exit(main())
