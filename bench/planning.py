"""Fallback planning: OMPL RRTConnect (batched checks), RRIS and a naive OMPL baseline.

Workload (deterministic, from `--seed`): the reference robot in the restroom with all stall
doors at 0°, 45° and 90°. Arm task configurations come from a seeded random search over the
arm's joint space: a configuration qualifies when it keeps 1 cm clearance at every base station
under every door angle, and it is filed by where its tool tip ends up in the base frame
(forward, down, up, left, right); the first two of each kind plus the stowed arm make the set.
Arm queries keep the base at a station (facing its stall or the sink) and move between two
configurations of the set; about 80% of them are chosen among pairs whose straight segment
collides (the rest are straight-line connectable). Base queries move between adjacent stations
with the arm stowed, both ways, under every door angle.

Planners, side by side on the same pairs and seeds, budget 2 s each:
- rrtconnect: `run_planning` → OMPL RRTConnect with the batched segment MotionValidator;
- rris: `run_planning` → RRIS;
- naive: OMPL RRTConnect with a per-state Python validity callback (one check call per state)
  and OMPL's default motion validation at an equivalent resolution.
Planning time is the search (endpoint checks and planner run); "total" adds shortcutting and
the certified validation. Per query (medians): "states" submitted to collision checking
(batched: every sample of a checked segment; naive: every state it asked about), "calls" into
the collision checker, "fcl" narrow-phase checks. The last line printed is one JSON object.

    python bench/planning.py            # 120 pairs
    python bench/planning.py --smoke    # 10 pairs, well under a minute
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from trajcache.geometry.collision import FREE, CollisionChecker
from trajcache.geometry.kinematics import link_transforms
from trajcache.geometry.reference.restroom import BaseStation, restroom_layout, restroom_scene
from trajcache.geometry.reference.robot import STOWED_ARM, reference_model, reference_urdf
from trajcache.geometry.robot import RobotModel
from trajcache.geometry.scene import Scene, scene_to_payload
from trajcache.planning.ompl_planner import plan_ompl
from trajcache.planning.problem import ModelSource, PlanningProblem, PlanResult, SceneSource
from trajcache.planning.run import run_planning
from trajcache.planning.space import MotionChecker, state_space_spec

DOOR_ANGLES = (0.0, 45.0, 90.0)
BUDGET_S = 2.0
ADJACENT = (("stall_1", "stall_2"), ("stall_2", "stall_3"), ("stall_3", "sink"))
# Tool-tip regions in the base frame (x forward, y left, z up; metres).
REGIONS: dict[str, Callable[[np.ndarray], bool]] = {
    "forward": lambda p: p[0] > 0.55 and abs(p[1]) < 0.25 and 0.5 < p[2] < 1.1,
    "down": lambda p: p[0] > 0.35 and p[2] < 0.5,
    "up": lambda p: p[2] > 1.2,
    "left": lambda p: p[1] > 0.4,
    "right": lambda p: p[1] < -0.4,
}
PER_REGION = 2
CLEARANCE_M = 0.01  # task configurations keep 1 cm from obstacles and from the robot itself
NONTRIVIAL_SHARE = 0.8


@dataclass(frozen=True)
class Pair:
    """One query: door angle, start and goal states, and what kind of query it is."""

    doors: float
    start: tuple[float, ...]
    goal: tuple[float, ...]
    kind: str  # "arm" | "base"
    straight_free: bool


def _base(station: BaseStation) -> list[float]:
    return [station.x, station.y, station.theta]


def task_configurations(
    model: RobotModel, scenes: dict[float, Scene], seed: int, draws: int = 4000
) -> dict[str, np.ndarray]:
    """~10 arm configurations free at every station under every door angle (seeded search)."""
    rng = np.random.default_rng(seed)
    off = model.arm_offset
    arms = rng.uniform(model.lower[off:], model.upper[off:], size=(draws, model.dof - off))
    free = np.ones(draws, dtype=bool)
    for station in restroom_layout().stations:
        states = np.hstack([np.tile(_base(station), (draws, 1)), arms])
        for scene in scenes.values():
            checker = CollisionChecker(model, scene)
            pads = (len(model.elements), len(checker.robot.pair_i))
            verdict = checker.check(
                states,
                element_pad=np.full((draws, pads[0]), CLEARANCE_M),
                pair_pad=np.full((draws, pads[1]), CLEARANCE_M),
                stop_at_first=False,
            )
            free &= verdict.status == FREE
    tip = model.link_names.index("tool_tip")
    at_origin = np.hstack([np.zeros((draws, off)), arms])
    tips = link_transforms(model, at_origin)[:, tip, :3, 3]
    chosen: dict[str, np.ndarray] = {"stowed": np.array(STOWED_ARM, dtype=float)}
    for region, inside in REGIONS.items():
        found = [k for k in np.flatnonzero(free) if inside(tips[k])][:PER_REGION]
        chosen.update({f"{region}_{n}": arms[k] for n, k in enumerate(found)})
    return chosen


def build_pairs(
    model: RobotModel, scenes: dict[float, Scene], count: int, seed: int
) -> tuple[list[Pair], dict[str, np.ndarray]]:
    """`count` fixed queries: base moves between adjacent stations, the rest arm moves."""
    rng = np.random.default_rng(seed)
    configs = task_configurations(model, scenes, seed)
    layout = restroom_layout()
    base_pairs: list[Pair] = []
    stowed = list(configs["stowed"])
    for doors, scene in scenes.items():
        for a, b in ADJACENT:
            for s, g in ((a, b), (b, a)):
                start = _base(layout.station(s)) + stowed
                goal = _base(layout.station(g)) + stowed
                free = _straight_free(model, scene, start, goal)
                base_pairs.append(Pair(doors, tuple(start), tuple(goal), "base", free))
    n_base = min(len(base_pairs), max(2, round(count * 0.15)))
    picked = [base_pairs[k] for k in sorted(rng.choice(len(base_pairs), n_base, replace=False))]
    names = sorted(configs)
    arm_pairs: dict[bool, list[Pair]] = {True: [], False: []}
    for doors, scene in scenes.items():
        for station in layout.stations:
            for i in names:
                for j in names:
                    if i == j:
                        continue
                    start = _base(station) + list(configs[i])
                    goal = _base(station) + list(configs[j])
                    free = _straight_free(model, scene, start, goal)
                    arm_pairs[free].append(Pair(doors, tuple(start), tuple(goal), "arm", free))
    n_arm = count - len(picked)
    hard = min(len(arm_pairs[False]), round(n_arm * NONTRIVIAL_SHARE))
    for free, n in ((False, hard), (True, n_arm - hard)):
        pool = arm_pairs[free]
        picked += [pool[k] for k in sorted(rng.choice(len(pool), n, replace=False))]
    return picked, configs


def _straight_free(model: RobotModel, scene: Scene, start: list[float], goal: list[float]) -> bool:
    a, b = np.array(start), np.array(goal)
    spec = state_space_spec(model, scene, around=(a, b))
    return MotionChecker(spec, scene).segment_free(a, b)


def run_pairs(
    pairs: list[Pair], planner: str, model: RobotModel, scenes: dict[float, Scene]
) -> list[PlanResult]:
    """Plan every pair with one planner ("naive" = the per-state OMPL baseline)."""
    source = ModelSource(
        model_id=model.model_id,
        urdf=reference_urdf(),
        base=model.base.value,
        joint_names=model.joint_names,
        allowed_pairs=tuple(sorted(model.allowed_pairs)),
    )
    sources = {d: SceneSource(s.hash, scene_to_payload(s)) for d, s in scenes.items()}
    results = []
    for seed, pair in enumerate(pairs):
        if planner == "naive":
            result = plan_ompl(
                model, scenes[pair.doors], pair.start, pair.goal,
                planner="rrtconnect", budget_s=BUDGET_S, seed=seed, naive=True,
            )  # fmt: skip
        else:
            problem = PlanningProblem(
                source, sources[pair.doors], pair.start, pair.goal,
                budget_s=BUDGET_S, planner=planner, seed=seed,
            )  # fmt: skip
            result = run_planning(problem)
        results.append(result)
    return results


def summarize(results: list[PlanResult]) -> dict[str, float]:
    """Success rate, planning/total time percentiles, path lengths and checks."""
    solved = [r for r in results if r.solved]

    def med(key: str, rows: list[PlanResult]) -> float:
        values = [r.stats.get(key, 0.0) for r in rows]
        return float(statistics.median(values)) if values else float("nan")

    plan = [r.stats.get("plan_ms", 0.0) for r in results]
    total = [r.stats.get("total_ms", r.stats.get("plan_ms", 0.0)) for r in results]
    return {
        "success_rate": len(solved) / len(results),
        "median_ms": float(np.median(plan)),
        "p95_ms": float(np.percentile(plan, 95)),
        "median_total_ms": float(np.median(total)),
        "p95_total_ms": float(np.percentile(total, 95)),
        "length_before": med("length_before", solved),
        "length_after": med("length_after", solved),
        "checks": med("checks", results),
        "check_calls": med("check_calls", results),
        "narrow_checks": med("narrow_checks", results),
    }


def main() -> None:
    """Build the pairs, run the three planners, print a table and one JSON line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="10 pairs")
    parser.add_argument("--pairs", type=int, default=120)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    count = 10 if args.smoke else max(100, args.pairs)
    began = time.perf_counter()
    model = reference_model()
    scenes = {d: restroom_scene(doors=d) for d in DOOR_ANGLES}
    pairs, configs = build_pairs(model, scenes, count, args.seed)
    kinds = {k: sum(p.kind == k for p in pairs) for k in ("arm", "base")}
    straight = sum(p.straight_free for p in pairs)
    print(
        f"pairs: {len(pairs)} (seed {args.seed}; {kinds['arm']} arm, {kinds['base']} base; "
        f"{straight} straight-line free); doors {DOOR_ANGLES}; "
        f"task configurations: {', '.join(sorted(configs))}; built in "
        f"{time.perf_counter() - began:.1f} s"
    )
    summary: dict[str, dict[str, float]] = {}
    for planner in ("rrtconnect", "rris", "naive"):
        t = time.perf_counter()
        results = run_pairs(pairs, planner, model, scenes)
        summary[planner] = summarize(results)
        summary[planner]["wall_s"] = time.perf_counter() - t
        failures = [r for r in results if not r.solved]
        for r in failures[:3]:
            print(f"  {planner} failure: {r.status.value}: {r.message[:120]}")
    header = (
        f"{'planner':<11}{'success':>8}{'plan med':>10}{'plan p95':>10}{'total med':>11}"
        f"{'total p95':>11}{'len raw':>9}{'len short':>10}{'states':>8}{'calls':>7}{'fcl':>7}"
        f"{'wall s':>8}"
    )
    print(header)
    print("-" * len(header))
    for planner, s in summary.items():
        print(
            f"{planner:<11}{s['success_rate']:>8.3f}{s['median_ms']:>10.1f}{s['p95_ms']:>10.1f}"
            f"{s['median_total_ms']:>11.1f}{s['p95_total_ms']:>11.1f}{s['length_before']:>9.2f}"
            f"{s['length_after']:>10.2f}{s['checks']:>8.0f}{s['check_calls']:>7.0f}"
            f"{s['narrow_checks']:>7.0f}{s['wall_s']:>8.1f}"
        )
    ours, rris, naive = summary["rrtconnect"], summary["rris"], summary["naive"]
    line = {
        "success_rate": round(ours["success_rate"], 4),
        "median_ms": round(ours["median_ms"], 2),
        "p95_ms": round(ours["p95_ms"], 2),
        "median_total_ms": round(ours["median_total_ms"], 2),
        "rris_success_rate": round(rris["success_rate"], 4),
        "rris_median_ms": round(rris["median_ms"], 2),
        "naive_success_rate": round(naive["success_rate"], 4),
        "naive_median_ms": round(naive["median_ms"], 2),
        "speedup_vs_naive": round(naive["median_ms"] / max(ours["median_ms"], 1e-9), 2),
        "pairs": len(pairs),
        "straight_free_pairs": straight,
        "budget_s": BUDGET_S,
    }
    print(json.dumps(line))


if __name__ == "__main__":
    main()
