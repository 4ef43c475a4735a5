"""The live service on real robot descriptions: registration, planning, cache hits, dense checks.

Starts `trajcache serve` (uvicorn on loopback, a temporary SQLite database) and, for each robot
of `example-robot-data` (trajcache.reference.example_robots; --robots to choose):

- Registers it as shipped: URDF, SRDF, a zip of its meshes, and its SRDF group or its listed
  planning joints (--without-srdf: URDF and planning joints only, and the dense check then
  applies no SRDF either). A failed registration is reported with the service's message.
- Generates seeded problems (scene_families: table, shelf, box, cage; scaled to the robot's
  reach; start and goal free by the dense check, sampled within both the URDF's and the service's
  limits). Each problem gets its own robot, its scene uploaded with PUT, and one plan request
  (fallback planning on, --budget seconds, the default planner or --planner).
- Replays every problem --replays times with ±0.02 uniform noise on every start and goal value
  (seeded; redrawn until free), after all problems of the robot were planned: how often the
  cache answers, and how fast the server is then (its `timings_ms.total`).
- Checks every returned path with the independent dense check (dense_mesh: Pinocchio and coal on
  the shipped meshes, steps 4× finer than the paper's, no padding): samples in contact with the
  scene, in self-collision, or out of joint limits, and whether it runs from start to goal.

One more row, `tiago-torso`: TIAGo planning its torso lift and arm (8 joints) on a fixed base,
in shelf, box and cage scenes whose goals lie 2-5 cm from the scene (the least distance by coal),
as tight as MotionBenchMaker's goals in shelves and boxes.

`plan_ms` is the client's latency of the first request of each problem (a miss: it plans).
Prints a table with a row per robot; the last line is one JSON object with the figures, over all
robots and per robot. Exits 1 when a returned path collides or the service answered 5xx.

    python bench/real_robots.py [--smoke] [--robots panda,ur5] [--problems N] [--budget S]
                                [--planner NAME]
"""

from __future__ import annotations

import argparse
import io
import json
import sys
import time
import zipfile
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dense_mesh import FloatArray, MeshChecker
from harness.service import running_service
from robot_description import describe
from scene_families import FAMILIES, Problem, Workspace, generate_problem, workspace
from trajcache.reference.example_robots import ROBOTS, ExampleRobot
from trajcache_client import NO_RETRY, APIError, Client, PlanResult

NOISE = 0.02
COLUMNS = ("problems", "success_rate", "plan_ms_median", "plan_ms_p95", "hit_rate",
           "hit_server_ms_median", "collisions", "self_collisions", "limit_violations")  # fmt: skip
HIT_PARTS = ("validate", "lookup", "db")  # of a hit's server time
PLAN_PARTS = (
    "plan",
    "setup",
    "search",
    "simplify",
    "certify",
    "repair",
    "worker",
    "pool",
    "validate",
    "db",
    "total",
)  # of a solved first request's server time
SMOKE_ROBOTS, SMOKE_FAMILIES = ("panda", "ur5"), ("table", "shelf")
# TIAGo planning with its torso (arm + torso lift, 8 joints) on a fixed base, in scenes as tight
# as MotionBenchMaker's: goals 2-5 cm from the shelf boards, box walls and cage bars.
TIGHT = ExampleRobot(
    "tiago-torso",
    "tiago_description/robots/tiago.urdf",
    joint_names=("torso_lift_joint", *(f"arm_{k}_joint" for k in range(1, 8))),
)
TIGHT_FAMILIES, TIGHT_CLEARANCE = ("shelf", "box", "cage"), (0.02, 0.05)
BENCH_ROBOTS = {**ROBOTS, TIGHT.name: TIGHT}


@dataclass
class Tally:
    """What one robot's requests gave."""

    robot: str
    registered: bool = False
    message: str = ""  # the service's answer to a failed registration
    problems: int = 0
    solved: int = 0
    goals_in_region: int = 0
    plan_ms: list[float] = field(default_factory=list)
    replays: int = 0
    hits: int = 0
    hit_server_ms: list[float] = field(default_factory=list)
    hit_parts_ms: dict[str, list[float]] = field(default_factory=dict)  # validate, lookup, db
    plan_parts_ms: dict[str, list[float]] = field(default_factory=dict)  # of solved first asks
    counts: Counter[str] = field(default_factory=Counter)  # paths, collisions, 4xx, …
    notes: Counter[str] = field(default_factory=Counter)  # 4xx messages, contact pairs, errors

    def figures(self) -> dict[str, Any]:
        """The robot's figures for the JSON line."""
        return {"registered": self.registered, **summary([self])}


def _percentile(values: list[float], q: float = 50) -> float | None:
    return round(float(np.percentile(values, q)), 2) if values else None


def summary(tallies: list[Tally]) -> dict[str, Any]:
    """Figures over the tallies of several robots."""
    problems = sum(t.problems for t in tallies)
    replays = sum(t.replays for t in tallies)
    plan_ms = [v for t in tallies for v in t.plan_ms]
    counts = sum((t.counts for t in tallies), Counter[str]())
    return {
        "problems": problems,
        "success_rate": round(sum(t.solved for t in tallies) / problems, 3) if problems else None,
        "plan_ms_median": _percentile(plan_ms),
        "plan_ms_p95": _percentile(plan_ms, 95),
        "hit_rate": round(sum(t.hits for t in tallies) / replays, 3) if replays else None,
        "hit_server_ms_median": _percentile([v for t in tallies for v in t.hit_server_ms]),
        **{
            f"hit_{part}_ms_median": _percentile(
                [v for t in tallies for v in t.hit_parts_ms.get(part, [])]
            )
            for part in HIT_PARTS
        },
        **{
            f"plan_{part}_ms_median": _percentile(
                [v for t in tallies for v in t.plan_parts_ms.get(part, [])]
            )
            for part in PLAN_PARTS
        },
        "collisions": counts["collisions"],
        "self_collisions": counts["self_collisions"],
        "limit_violations": counts["limit_violations"],
        "endpoint_errors": counts["endpoint_errors"],
        "paths_checked": counts["paths"],
        "dense_samples": counts["dense_samples"],
        "replays": replays,
        "replays_planned": counts["replays_planned"],  # a success, but not from the cache
        "replays_failed": counts["replays_failed"],
        "goals_in_region": sum(t.goals_in_region for t in tallies),
        "http_4xx": counts["http_4xx"],
        "http_5xx": counts["http_5xx"],
    }


def mesh_archive(robot: ExampleRobot) -> bytes:
    """The robot's mesh files as a zip, by their path below robots/."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for path, data in robot.files().items():
            archive.writestr(path, data)
    return buffer.getvalue()


def registration(
    robot: ExampleRobot, planning_joints: list[str], with_srdf: bool
) -> dict[str, Any]:
    """The keyword arguments of `Client.register_model`: the robot as shipped."""
    fields: dict[str, Any] = {"base": robot.base, "name": robot.name,
                              "archive": mesh_archive(robot)}  # fmt: skip
    if with_srdf and robot.srdf is not None:
        fields["srdf"] = robot.srdf
    if with_srdf and robot.group is not None:
        fields["group"] = robot.group
    elif robot.joint_names is not None or not with_srdf:
        fields["joint_names"] = planning_joints
    if robot.joint_values:
        fields["joint_values"] = robot.joint_values
    return fields


def _limits(values: list[float | None], unbounded: float) -> FloatArray:
    return np.array([unbounded if v is None else v for v in values], dtype=float)


class RobotRun:
    """One registered robot: its problems planned, replayed and checked through the service."""

    def __init__(
        self, client: Client, tally: Tally, model_id: str, checker: MeshChecker, ws: Workspace
    ) -> None:
        self.client, self.tally, self.model_id = client, tally, model_id
        self.checker, self.ws = checker, ws

    def ask(
        self, robot_id: str, start: FloatArray, goal: FloatArray, options: dict[str, Any]
    ) -> tuple[float, PlanResult | None]:
        """Send a plan request; its latency (ms) and its answer, None for a 4xx or 5xx."""
        began = time.perf_counter()
        try:
            answer = self.client.plan(robot_id, start.tolist(), goal.tolist(), options)
        except APIError as exc:
            latency = (time.perf_counter() - began) * 1e3
            kind = "http_5xx" if exc.status_code >= 500 else "http_4xx"
            self.tally.counts[kind] += 1
            self.tally.notes[f"{exc.status_code}: {exc.detail[:160]}"] += 1
            return latency, None
        return (time.perf_counter() - began) * 1e3, answer

    def check(self, answer: PlanResult, start: FloatArray, goal: FloatArray) -> None:
        """Dense-check a returned path in the scene the checker holds."""
        states = np.asarray(answer.states, dtype=float)
        verdict = self.checker.check_path(states)
        counts = self.tally.counts
        counts["paths"] += 1
        counts["dense_samples"] += verdict.samples
        counts["collisions"] += verdict.collides
        counts["self_collisions"] += verdict.self_collides
        counts["limit_violations"] += verdict.limit_samples > 0
        ends = np.abs(np.stack([states[0] - start, states[-1] - goal]))
        if self.checker.planar:
            ends[:, 2] = np.abs((ends[:, 2] + np.pi) % (2 * np.pi) - np.pi)
        counts["endpoint_errors"] += bool(ends.max() > 1e-6)
        for pair, n in (verdict.scene_pairs + verdict.self_pairs).items():
            self.tally.notes[
                f"contact {pair} ({answer.source}, depth ≤ {verdict.max_depth * 1e3:.1f} mm)"
            ] += n

    def plan(self, problem: Problem, options: dict[str, Any]) -> None:
        """Create the problem's robot, upload its scene and plan it."""
        robot_id = f"{self.tally.robot}-{problem.family}-{problem.index}"
        self.client.put_robot(robot_id, self.model_id)
        self.client.put_scene(robot_id, {"objects": list(problem.objects)})
        self.checker.set_scene(problem.objects)
        latency, answer = self.ask(robot_id, problem.start, problem.goal, options)
        self.tally.plan_ms.append(latency)
        if answer is not None and answer.status == "success":
            self.tally.solved += 1
            for part, value in answer.timings_ms.items():
                self.tally.plan_parts_ms.setdefault(part, []).append(float(value))
            self.check(answer, problem.start, problem.goal)
        elif answer is not None:
            self.tally.notes[f"{answer.status} ({robot_id}): {answer.message[:120]}"] += 1

    def replay(self, problem: Problem, options: dict[str, Any], rng: np.random.Generator) -> None:
        """Ask the problem again with noisy start and goal, both free."""
        robot_id = f"{self.tally.robot}-{problem.family}-{problem.index}"
        self.checker.set_scene(problem.objects)
        start, goal = self.noisy(problem.start, rng), self.noisy(problem.goal, rng)
        if start is None or goal is None:
            self.tally.counts["replays_skipped"] += 1
            return
        self.tally.replays += 1
        _, answer = self.ask(robot_id, start, goal, options)
        if answer is None:
            return
        for rejected in answer.rejected:  # why a cached path did not serve
            self.tally.notes[f"replay: candidate {rejected.reason[:100]}"] += 1
        if answer.status != "success":
            self.tally.counts["replays_failed"] += 1
            return
        if answer.source == "cache":
            self.tally.hits += 1
            timings = answer.timings_ms
            self.tally.hit_server_ms.append(float(timings["total"]))
            for part in HIT_PARTS:
                self.tally.hit_parts_ms.setdefault(part, []).append(float(timings[part]))
        else:
            self.tally.counts["replays_planned"] += 1
        self.check(answer, start, goal)

    def noisy(self, state: FloatArray, rng: np.random.Generator) -> FloatArray | None:
        """The state with uniform noise, within the limits and free; None after 20 draws."""
        for _ in range(20):
            out = np.clip(
                state + rng.uniform(-NOISE, NOISE, len(state)), self.ws.lower, self.ws.upper
            )
            if self.checker.is_free(out):
                return out
        return None


def run_robot(client: Client, robot: ExampleRobot, args: argparse.Namespace) -> Tally:
    """Register one robot, plan and replay its problems; its tally."""
    tally = Tally(robot.name)
    local = describe(robot, srdf=not args.without_srdf)
    fields = registration(robot, list(local.joint_names), not args.without_srdf)
    try:
        model_id = client.register_model(robot.urdf, **fields).model_id
    except APIError as exc:
        tally.message = f"{exc.status_code}: {exc.detail[:300]}"
        tally.counts["http_5xx" if exc.status_code >= 500 else "http_4xx"] += 1
        return tally
    tally.registered = True
    detail = client.get_model(model_id)
    joints = detail.joint_names
    if list(local.joint_names) != joints:
        tally.notes[f"planning joints: service {joints}, local {list(local.joint_names)}"] += 1
    held = detail.held_joints or robot.joint_values
    checker = MeshChecker(
        describe(robot, joint_names=joints, held=held, srdf=not args.without_srdf)
    )
    lower, upper = _limits(detail.lower, -np.inf), _limits(detail.upper, np.inf)
    ws = workspace(checker, args.seed, lower, upper)
    run = RobotRun(client, tally, model_id, checker, ws)
    options: dict[str, Any] = {"fallback": True, "budget_s": args.budget}
    if args.planner:  # OMPL's, say, to tell a hard problem from one with no path
        options["planner"] = args.planner
    problems = []
    tight = robot.name == TIGHT.name
    clearance = TIGHT_CLEARANCE if tight else None
    for family in [f for f in args.families if f in TIGHT_FAMILIES] if tight else args.families:
        for index in range(args.problems):
            problem = generate_problem(checker, ws, family, index, args.seed, clearance)
            if problem is None:
                tally.notes[f"no free start or goal in {family} {index}"] += 1
                continue
            problems.append(problem)
            tally.problems += 1
            tally.goals_in_region += problem.goal_in_region
            run.plan(problem, options)
    rng = np.random.default_rng([args.seed, 99])
    for _ in range(args.replays):
        for problem in problems:
            run.replay(problem, options, rng)
    return tally


def print_table(tallies: list[Tally], wall_s: float) -> None:
    """A row per robot, then the notes."""
    head = (
        "robot",
        "problems",
        "success",
        "plan ms p50",
        "p95",
        "hit rate",
        "hit srv ms",
        "collide",
        "self",
        "limits",
    )
    print("".join(f"{h:>12}" for h in head))
    for t in tallies:
        f = t.figures()
        if not t.registered:
            print(f"{t.robot:>12}  not registered: {t.message}")
            continue
        row = (t.robot, *(f[k] for k in COLUMNS))
        print("".join(f"{v!s:>12}" for v in row))
    for t in tallies:
        for note, n in t.notes.most_common(8):
            print(f"  {t.robot}: {n} × {note}")
    print(f"wall time {wall_s:.1f} s")


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark, print the table and the JSON line; 1 when a path collided or a 5xx."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument(
        "--robots", help=f"comma-separated, of {', '.join(BENCH_ROBOTS)} (default all)"
    )
    parser.add_argument("--families", help=f"comma-separated, of {', '.join(FAMILIES)}")
    parser.add_argument("--problems", type=int, help="problems per family (default 5; smoke 1)")
    parser.add_argument("--replays", type=int, default=1, help="noisy replays per problem")
    parser.add_argument("--budget", type=float, help="planning budget s (default 5; smoke 2)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--planner", help="the planner of every request (default the service's)")
    parser.add_argument("--without-srdf", action="store_true", help="register URDF and joints only")
    parser.add_argument("--smoke", action="store_true", help="a short run for CI")
    args = parser.parse_args(argv)
    every = SMOKE_ROBOTS if args.smoke else BENCH_ROBOTS
    names = args.robots.split(",") if args.robots else list(every)
    args.families = (
        args.families.split(",")
        if args.families
        else list(SMOKE_FAMILIES if args.smoke else FAMILIES)
    )
    args.problems = args.problems or (1 if args.smoke else 5)
    args.budget = args.budget or (2.0 if args.smoke else 5.0)
    began = time.perf_counter()
    tallies = []
    with running_service() as base, Client(base, timeout=120, retry=NO_RETRY) as client:
        for name in names:
            tallies.append(run_robot(client, BENCH_ROBOTS[name], args))
    wall_s = time.perf_counter() - began
    print_table(tallies, wall_s)
    figures = {
        "robots_tried": len(tallies),
        "robots_registered": sum(t.registered for t in tallies),
        **summary(tallies),
        "per_robot": {t.robot: t.figures() for t in tallies},
        "registration_errors": {t.robot: t.message for t in tallies if not t.registered},
        "budget_s": args.budget,
        "planner": args.planner,
        "seed": args.seed,
        "wall_s": round(wall_s, 1),
        "smoke": args.smoke,
    }
    print(json.dumps(figures))
    return 1 if figures["collisions"] or figures["self_collisions"] or figures["http_5xx"] else 0


if __name__ == "__main__":
    sys.exit(main())
