"""`bench/pose_goals.py --cartesian`: straight approach and retreat moves of the MBM Panda's hand.

From each MotionBenchMaker Panda problem's goal state (`../shared/data/mbm-panda`), two 10 cm
straight moves of `panda_hand` along its approach axis (its z): forward (approach) and back
(retreat), sent to `POST /v1/robots/{id}/cartesian-path` through the REST API, in the
problem's scene. A move is kept when it is feasible without the service's word
(`cartesian_filter`, sharing no code with the service: an independent IK path along the line,
within the joint limits, with the whole robot clear along it); the others are counted by reason
(`filtered`). For each kept move:

- `cartesian_success_rate`: answers that reach fraction 1.0; the others are listed by reason
  (status, and what it hit); filtered moves are asked too (their answers are checked alike)
  and those the service completes anyway are counted (`filtered_but_complete`);
- every answered path is dense-checked (`mbm_check.check_path`: `collisions`), and the hand's
  origin at each state and midway between states (yourdfpy) must lie within the answer's
  `max_deviation_m` of the line (`line_errors`);
- a repeat with the start's joints moved by up to 4 mrad each (scaled down where the hand would
  move by more than 5 mm: `repeat_start_shift_mm_max`) and the waypoint by up to 5 mm, with the
  cache tolerances widened to cover them (5 mrad, 6 mm): `cartesian_hit_rate` is the share
  served from the cache.

Prints a table and ends with one JSON line.
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from cartesian_filter import LineIk, infeasible_reason
from harness.report import print_checked
from harness.service import running_service
from mbm_check import check_path
from mbm_problems import FAMILIES, allowed_pairs, clamp, load_problems, scene_objects, unpacked
from mbm_tally import Tally, percentile
from trajcache_client import NO_RETRY, APIError, Client

LINK = "panda_hand"
MOVE_M = 0.10
START_JITTER_RAD = 4e-3
WAYPOINT_JITTER_M = 0.005
CACHE = {"joint_tolerance": 5e-3, "position_tolerance": 6e-3}


def miss_reason(answer: dict[str, Any]) -> str:
    """The status of a path stopped short, with what it hit (links and objects, not states)."""
    message = answer["message"]
    if answer["status"] in ("collision", "too_close"):
        message = message.split(" (on the motion")[0].split(" (at the start")[0]
    elif answer["status"] == "no_ik_solution":
        message = message.split(" at sample")[0]
    return f"{answer['status']}: {message[:100]}"


class CartesianRun:
    """The moves through a running service, with tallies of what came back."""

    def __init__(self, client: Client, args: argparse.Namespace, run: Any) -> None:
        self.client, self.args, self.run = client, args, run  # run: pose_goals.PoseRun
        self.counts: Counter[str] = Counter()
        self.reasons: Counter[str] = Counter()
        self.times: dict[str, list[float]] = {"computed": [], "hit": []}
        self.shifts: list[float] = []
        self.filtered: Counter[str] = Counter()
        self.bonus: Counter[str] = Counter()  # filtered moves the service completed anyway
        self.ik = LineIk(run.checker, LINK)

    def ask(self, robot_id: str, body: dict[str, Any]) -> dict[str, Any] | None:
        try:
            return self.client.cartesian_path(robot_id, body).model_dump()
        except APIError as exc:
            self.counts["http_5xx" if exc.status_code >= 500 else "http_4xx"] += 1
            return None

    def check(self, tally: Tally, answer: dict[str, Any], line: tuple[Any, Any]) -> None:
        states = np.asarray(answer["states"], dtype=float)
        check_path(tally, self.run.checker, states, (states[0], states[-1]), "cartesian")
        a, b = np.asarray(line[0]), np.asarray(line[1])
        mids = (states[:-1] + states[1:]) / 2 if len(states) > 1 else states[:0]
        for state in [*states, *mids]:
            p = self.run.hand.of(state)[:3, 3]
            t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
            gap = float(np.linalg.norm(p - (a + t * (b - a))))
            self.counts["line_errors"] += gap > answer["max_deviation_m"] + 1e-9

    def jittered(self, state: np.ndarray, pose: np.ndarray, rng: Any) -> np.ndarray:
        """The start with every joint moved by up to 4 mrad, scaled down where that would move
        the hand by more than 5 mm."""
        step = rng.uniform(-1, 1, state.shape) * START_JITTER_RAD
        lower, upper = self.run.checker.lower, self.run.checker.upper
        start = np.clip(state + step, lower, upper)
        shift = float(np.linalg.norm(self.run.hand.of(start)[:3, 3] - pose[:3, 3]))
        if shift > WAYPOINT_JITTER_M:
            start = np.clip(state + step * 0.95 * WAYPOINT_JITTER_M / shift, lower, upper)
            shift = float(np.linalg.norm(self.run.hand.of(start)[:3, 3] - pose[:3, 3]))
        self.shifts.append(shift)
        return start

    def move(self, tally: Tally, robot_id: str, state: np.ndarray, sign: float, rng: Any) -> None:
        pose = self.run.hand.of(state)
        shift = sign * MOVE_M * pose[:3, 2]
        quat = self.run.hand.goal(state)["orientation"]
        end = pose[:3, 3] + shift
        body = {"start": state.tolist(), "link": LINK, "cache": CACHE,
                "waypoints": [{"position": end.tolist(), "orientation": quat}]}  # fmt: skip
        reason = infeasible_reason(self.ik, state, shift)
        answer = self.ask(robot_id, {**body, "cache": {**CACHE, "store": not reason}})
        if answer is not None:
            self.check(tally, answer, (pose[:3, 3], end))
        if reason:  # asked all the same: checked, and a whole path counts as a bonus
            self.filtered[reason] += 1
            self.bonus[reason] += answer is not None and answer["fraction"] == 1.0
            return
        self.counts["moves"] += 1
        if answer is None:
            return
        if answer["fraction"] < 1.0:
            self.reasons[miss_reason(answer)] += 1
            return
        self.counts["complete"] += 1
        self.times["computed"].append(answer["timings_ms"]["total"])
        start = self.jittered(state, pose, rng)
        jitter = rng.normal(size=3)
        moved = end + jitter / np.linalg.norm(jitter) * rng.uniform(0, WAYPOINT_JITTER_M)
        body = {**body, "start": start.tolist()}
        body["waypoints"] = [{"position": moved.tolist(), "orientation": quat}]
        self.counts["repeats"] += 1
        again = self.ask(robot_id, body)
        if again is None:
            return
        self.check(tally, again, (self.run.hand.of(start)[:3, 3], moved))
        if again["source"] == "cache":
            self.counts["hits"] += 1
            self.times["hit"].append(again["timings_ms"]["total"])

    def problem(self, tally: Tally, problem: Any) -> None:
        robot_id = f"cartesian-{problem.label}"
        goal, _ = clamp(problem.goal, self.run.checker.lower, self.run.checker.upper)
        self.client.put_robot(robot_id, self.run.model_id)
        self.client.put_scene(robot_id, problem.scene_text, media_type="application/yaml")
        self.run.checker.set_scene(scene_objects(problem.scene), allowed_pairs(problem.scene))
        tally.problems += 1
        rng = np.random.default_rng([self.args.seed, FAMILIES.index(problem.family), problem.index])
        for sign in (1.0, -1.0):  # approach, then retreat
            self.move(tally, robot_id, goal, sign, rng)


def main(args: argparse.Namespace, run_class: Any) -> int:
    """Run the moves of every problem; print the table and the JSON line."""
    began = time.perf_counter()
    problems = load_problems(unpacked(args.data), list(FAMILIES), args.per_family)
    tallies: dict[str, Tally] = {}
    with running_service() as base, Client(base, timeout=120, retry=NO_RETRY) as client:
        bench = CartesianRun(client, args, run_class(client, args))
        for problem in problems:
            bench.problem(tallies.setdefault(problem.family, Tally(problem.family)), problem)
    counts = sum((t.counts for t in tallies.values()), bench.counts)
    table = Table(title="MotionBenchMaker, Panda, 10 cm Cartesian approach and retreat")
    table.add_column("misses (fraction < 1), by reason")
    table.add_column("n")
    for reason, n in bench.reasons.most_common():
        table.add_row(reason, str(n))
    Console(width=140).print(table)
    moves, repeats = counts["moves"], counts["repeats"]
    figures = {
        "problems": sum(t.problems for t in tallies.values()),
        "moves": moves,
        "filtered": dict(bench.filtered),
        "filtered_but_complete": dict(bench.bonus),
        "cartesian_success_rate": round(counts["complete"] / moves, 4) if moves else None,
        "cartesian_ms_median": percentile(bench.times["computed"]),
        "repeats": repeats,
        "cartesian_hit_rate": round(counts["hits"] / repeats, 4) if repeats else None,
        "hit_ms_median": percentile(bench.times["hit"]),
        "repeat_start_shift_mm_max": round(max(bench.shifts, default=0.0) * 1e3, 2),
    }
    return print_checked(figures, counts, check="line_errors", began=began, smoke=args.smoke)
