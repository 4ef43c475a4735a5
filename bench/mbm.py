"""The MotionBenchMaker Panda problems through the REST API, dense-checked independently.

The data set is `../shared/data/mbm-panda` from the repository root (--data): 7 families ×
100 problems, each a MoveIt `PlanningScene` and `MotionPlanRequest` as YAML (mbm_problems).
Starts `trajcache serve` (uvicorn on loopback, a temporary SQLite database), then, as a robot
team would over HTTP:

- Registers the Panda as shipped: `robot/panda.urdf`, `robot/panda.srdf` (group `panda_arm`)
  and a zip of its collision meshes.
- Per problem: its own robot, the scene YAML PUT to `/v1/robots/{id}/scene` as it is
  (`application/yaml`), and one native plan request (`POST /v1/robots/{id}/plan`): start and goal
  are the request's seven arm joint values (a goal outside the joint limits is clamped into them
  and counted, `clamped_goals`), fallback planning with --budget seconds and `lookup: false`
  (the native request, so that --budget and --planner apply as given; the MoveIt request files
  themselves are accepted as sent, `tests/api/test_mbm_requests.py`). --planner names the
  planner of every request.
- Replays each solved problem once, start and goal moved by uniform noise of up to ±0.02 rad per
  joint (seeded per problem, within the limits, redrawn until free by the dense check), with the
  lookup on: whether the cache answers (`source` "cache"), and the server's time then.
- Dense-checks every returned path (mbm_check: Pinocchio and coal on the shipped meshes, steps 4×
  finer than the paper's, no padding, the SRDF's and the scene's allowed pairs skipped): samples
  in contact with the scene or in self-collision, out of the joint limits, and wrong endpoints.

--cross-scene also asks each solved problem again in its own scene with one object moved by up
to 1 cm, and in its family's next scene (mbm_cross). --in-process times the planner alone on
the same problems, without HTTP (mbm_inprocess). The
figures and what each timing measures are in mbm_tally. Prints a table per family; the last
line is one JSON object. Exits 1 when a returned path collides or the service answered 5xx.

    python bench/mbm.py [--smoke] [--per-family N] [--families box,cage] [--budget S]
                        [--planner NAME] [--seed N] [--in-process] [--cross-scene]
                        [--data DIR]
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
from rich.console import Console

import mbm_check
from dense_mesh import FloatArray
from harness.mbm_panda import register_panda
from harness.service import running_service
from mbm_check import SceneChecker, check_path, panda_description, path_length
from mbm_cross import CrossScenes
from mbm_problems import (
    DEFAULT_DATA,
    FAMILIES,
    Problem,
    allowed_pairs,
    clamp,
    load_problems,
    scene_objects,
    unpacked,
)
from mbm_tally import Tally, print_table, summary
from trajcache_client import NO_RETRY, APIError, Client, PlanResult

NOISE = 0.02  # rad per joint, uniform, of a replay's start and goal
NOISY_DRAWS = 20  # a replay is skipped when no free noisy state came up in as many draws
SMOKE_PER_FAMILY, SMOKE_BUDGET_S, BUDGET_S = 2, 2.0, 5.0


def planner_ms(timings: dict[str, float]) -> float:
    """The planner's time in an answer's timings (see mbm_tally)."""
    if "search" in timings and "simplify" in timings:
        return timings["search"] + timings["simplify"]
    return timings["plan"]


class ServiceRun:
    """The problems planned, replayed and checked through one service."""

    def __init__(self, client: Client, checker: SceneChecker, args: argparse.Namespace) -> None:
        self.client, self.checker, self.args = client, checker, args
        self.options: dict[str, Any] = {"fallback": True, "budget_s": args.budget}
        if args.planner:
            self.options["planner"] = args.planner
        model = register_panda(client, args.data / "robot")
        detail = client.get_model(model.model_id)
        if tuple(detail.joint_names) != tuple(checker.robot.joint_names):
            raise RuntimeError(f"the service plans {detail.joint_names}, not the arm joints")
        self.model_id = model.model_id
        service_lower = np.array([-np.inf if v is None else v for v in detail.lower])
        service_upper = np.array([np.inf if v is None else v for v in detail.upper])
        self.lower = np.maximum(checker.lower, service_lower)  # the URDF's and the service's
        self.upper = np.minimum(checker.upper, service_upper)

    def ask(
        self, tally: Tally, robot_id: str, ends: tuple[FloatArray, FloatArray], lookup: bool
    ) -> PlanResult | None:
        """A plan request's answer; None for a 4xx or 5xx (counted, its message noted)."""
        options = {**self.options, "lookup": lookup}
        try:
            return self.client.plan(robot_id, ends[0].tolist(), ends[1].tolist(), options)
        except APIError as exc:
            tally.counts["http_5xx" if exc.status_code >= 500 else "http_4xx"] += 1
            tally.notes[f"{exc.status_code}: {exc.detail[:160]}"] += 1
            return None

    def plan(self, tally: Tally, problem: Problem) -> tuple[FloatArray, FloatArray] | None:
        """Upload the problem's scene and plan it fresh; its endpoints when solved."""
        robot_id = f"mbm-{problem.label}"
        tally.problems += 1
        start, moved_start = clamp(problem.start, self.lower, self.upper)
        goal, moved_goal = clamp(problem.goal, self.lower, self.upper)
        tally.clamped_starts += moved_start
        tally.clamped_goals += moved_goal
        try:
            self.client.put_robot(robot_id, self.model_id)
            self.client.put_scene(robot_id, problem.scene_text, media_type="application/yaml")
        except APIError as exc:
            tally.counts["http_5xx" if exc.status_code >= 500 else "http_4xx"] += 1
            tally.notes[f"scene {exc.status_code}: {exc.detail[:160]}"] += 1
            return None
        answer = self.ask(tally, robot_id, (start, goal), lookup=False)
        if answer is None or not answer.ok or answer.states is None:
            if answer is not None:
                tally.notes[f"{answer.status}: {answer.message[:120]}"] += 1
            return None
        tally.solved += 1
        tally.planner_ms.append(planner_ms(answer.timings_ms))
        tally.plan_ms.append(float(answer.timings_ms["total"]))
        tally.record_phases(answer.timings_ms)
        tally.record_extras(
            {**answer.timings_ms, **(answer.model_extra or {}), "planner": answer.planner}
        )
        states = np.asarray(answer.states, dtype=float)
        tally.path_lengths.append(path_length(states))
        check_path(tally, self.checker, states, (start, goal), f"plan {problem.label}")
        return start, goal

    def replay(self, tally: Tally, problem: Problem, ends: tuple[FloatArray, FloatArray]) -> None:
        """Ask the solved problem again with noisy start and goal, both free, lookup on."""
        rng = np.random.default_rng([self.args.seed, FAMILIES.index(problem.family), problem.index])
        start, goal = self.noisy(ends[0], rng), self.noisy(ends[1], rng)
        if start is None or goal is None:
            tally.counts["replays_skipped"] += 1
            return
        tally.replays += 1
        answer = self.ask(tally, f"mbm-{problem.label}", (start, goal), lookup=True)
        if answer is None or not answer.ok or answer.states is None:
            tally.counts["replays_failed"] += 1
            return
        if answer.source == "cache":
            tally.hits += 1
            tally.hit_server_ms.append(float(answer.timings_ms["total"]))
            tally.hit_validate_ms.append(float(answer.timings_ms["validate"]))
            proved = answer.validation.ends_proved if answer.validation is not None else None
            tally.hit_ends_proved.append(proved or 0.0)
            tally.record_phases(answer.timings_ms, hit=True)
        elif answer.source == "repaired":
            tally.repaired_server_ms.append(float(answer.timings_ms["total"]))
        else:
            tally.counts["replays_planned"] += 1
            for rejected in answer.rejected:  # why the cached path did not serve
                tally.notes[f"replay: candidate {rejected.reason[:100]}"] += 1
        check_path(
            tally, self.checker, np.asarray(answer.states, dtype=float), (start, goal),
            f"replay {problem.label}",
        )  # fmt: skip

    def moveit(self, tally: Tally, problem: Problem) -> None:
        """Send the problem's MotionPlanRequest file as it is to `/motion-plan` (its scene is
        up); count it accepted (HTTP 200) and solved, and dense-check the trajectory."""
        tally.counts["moveit_sent"] += 1
        try:
            answer = self.client.motion_plan(f"mbm-{problem.label}", problem.request_text)
        except APIError as exc:
            tally.counts["http_5xx" if exc.status_code >= 500 else "http_4xx"] += 1
            tally.notes[f"moveit {exc.status_code}: {exc.detail[:150]}"] += 1
            return
        tally.counts["moveit_accepted"] += 1
        if answer["error_code"]["val"] != 1:
            tally.notes[f"moveit: error code {answer['error_code']['val']}"] += 1
            return
        tally.counts["moveit_solved"] += 1
        trajectory = answer["trajectory"]["joint_trajectory"]
        order = [trajectory["joint_names"].index(n) for n in self.checker.robot.joint_names]
        states = np.array([[p["positions"][k] for k in order] for p in trajectory["points"]])
        ends = (clamp(problem.start, self.lower, self.upper)[0],
                clamp(problem.goal, self.lower, self.upper)[0])  # fmt: skip
        check_path(tally, self.checker, states, ends, f"moveit {problem.label}")

    def noisy(self, state: FloatArray, rng: np.random.Generator) -> FloatArray | None:
        """The state with uniform noise, within the limits and free; None after NOISY_DRAWS."""
        for _ in range(NOISY_DRAWS):
            out = np.clip(state + rng.uniform(-NOISE, NOISE, len(state)), self.lower, self.upper)
            if self.checker.is_free(out):
                return out
        return None

    def run(self, problems: list[Problem]) -> list[Tally]:
        """Plan, check and replay every problem, a tally per family."""
        tallies: dict[str, Tally] = {}
        cross = CrossScenes(self.client, self.checker, self.options)
        for problem in problems:
            tally = tallies.setdefault(problem.family, Tally(problem.family))
            self.checker.set_scene(scene_objects(problem.scene), allowed_pairs(problem.scene))
            ends = self.plan(tally, problem)
            if ends is not None:
                self.replay(tally, problem, ends)
            if self.args.moveit:
                self.moveit(tally, problem)
            if ends is not None and self.args.cross_scene:
                cross.moved(tally, problem, ends, self.args.seed)
                family = [p for p in problems if p.family == problem.family]
                other = family[(family.index(problem) + 1) % len(family)]
                if other is not problem:
                    cross.cross(tally, problem, ends, other)
        return list(tallies.values())


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line, with the smoke sizes and defaults filled in."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the mbm-panda folder")
    parser.add_argument("--families", help=f"comma-separated, of {', '.join(FAMILIES)}")
    parser.add_argument("--per-family", type=int, help="problems per family (default all)")
    parser.add_argument("--budget", type=float, help=f"planning budget s (default {BUDGET_S:g}; "
                        f"smoke {SMOKE_BUDGET_S:g})")  # fmt: skip
    parser.add_argument("--planner", help="the planner of every request (default: the service's)")
    parser.add_argument("--seed", type=int, default=1, help="of the replays' noise")
    parser.add_argument("--in-process", action="store_true", help="the planner alone, no HTTP")
    parser.add_argument("--smoke", action="store_true", help=f"{SMOKE_PER_FAMILY} per family")
    parser.add_argument(
        "--moveit", action="store_true", help="also send each request file as is to /motion-plan"
    )
    parser.add_argument(
        "--cross-scene", action="store_true", help="also ask in moved and in other scenes"
    )
    parser.add_argument("--dump-contacts", type=Path, help="append colliding paths here (JSONL)")
    args = parser.parse_args(argv)
    if args.dump_contacts:
        mbm_check.DUMP.append(args.dump_contacts)
    args.families = args.families.split(",") if args.families else list(FAMILIES)
    if unknown := set(args.families) - set(FAMILIES):
        parser.error(f"unknown families {sorted(unknown)}; use {', '.join(FAMILIES)}")
    if args.per_family is None and args.smoke:
        args.per_family = SMOKE_PER_FAMILY
    if args.budget is None:
        args.budget = SMOKE_BUDGET_S if args.smoke else BUDGET_S
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark, print the table and the JSON line; 1 when a path collided or a 5xx."""
    args = parse_args(argv)
    began = time.perf_counter()
    problems = load_problems(unpacked(args.data), args.families, args.per_family)
    checker = SceneChecker(panda_description(args.data / "robot"))
    extra: dict[str, Any] = {}
    if args.in_process:
        from mbm_inprocess import run_in_process  # imports the planner into this process

        tallies, extra = run_in_process(problems, checker, args)
    else:
        with running_service() as base, Client(base, timeout=120, retry=NO_RETRY) as client:
            tallies = ServiceRun(client, checker, args).run(problems)
    wall_s = time.perf_counter() - began
    print_table(tallies, args.in_process, Console(width=140))
    figures = {
        **summary(tallies, args.in_process),
        **extra,
        "mode": "in-process" if args.in_process else "http",
        "planner": args.planner,
        "budget_s": args.budget,
        "seed": args.seed,
        "wall_s": round(wall_s, 1),
        "smoke": args.smoke,
    }
    if args.moveit and not args.in_process:
        counts = sum((t.counts for t in tallies), Counter[str]())
        sent = counts["moveit_sent"]
        figures["as_sent_accepted_rate"] = (
            round(counts["moveit_accepted"] / sent, 4) if sent else None
        )
        figures["as_sent_solved_rate"] = round(counts["moveit_solved"] / sent, 4) if sent else None
    print(json.dumps(figures))
    return 1 if figures["collisions"] or figures["self_collisions"] or figures["http_5xx"] else 0


if __name__ == "__main__":
    sys.exit(main())
