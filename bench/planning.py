"""Fallback planning: the compiled planner (the default), OMPL RRTConnect (batched checks), RRIS
and a naive OMPL baseline.

Workload (deterministic, from `--seed`): planning calls drawn from the reference workload
generator (REFERENCE.md): three cleaning runs, each with its own door angles and execution noise,
and a pre-seeding door sweep with every door at 0°, 45° and 90°. Each call is planned in the
scene in force when the run makes it (doors, seats). Both arm moves at a station and base moves
between stations (arm stowed) are drawn; the table reports how many are straight-line free.

Planners, side by side on the same pairs and seeds, budget 2 s each:
- compiled: `run_planning` → the compiled RRT-Connect on sphere trees (`compiled_` keys);
- rrtconnect: `run_planning` → OMPL RRTConnect with the batched segment MotionValidator;
- rris: `run_planning` → RRIS;
- naive: OMPL RRTConnect with a per-state Python validity callback (one check call per state)
  and OMPL's default motion validation at an equivalent resolution.
Planning time is the search (endpoint checks and planner run); "total" adds shortcutting and
the certified validation; "detour med" is the median planning time over the calls whose
straight segment collides. Per query (medians): "states" submitted to collision checking
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
from dataclasses import dataclass

import numpy as np

from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.planning.motion import MotionChecker
from trajcache.planning.ompl_planner import plan_ompl
from trajcache.planning.options import SearchOptions
from trajcache.planning.problem import ModelSource, PlanningProblem, PlanResult, SceneSource
from trajcache.planning.run import run_planning
from trajcache.planning.space import state_space_spec
from trajcache.reference.cleaning import CleaningRun, cleaning_run, door_sweep_run
from trajcache.reference.robot import reference_model, reference_urdf

BUDGET_S = 2.0
SWEEP_DOORS_DEG = (0.0, 45.0, 90.0)


@dataclass(frozen=True)
class Pair:
    """One query: the scene it is planned in, start and goal states, and what kind it is."""

    scene: str  # hash of the scene in force at the call
    start: tuple[float, ...]
    goal: tuple[float, ...]
    kind: str  # "arm" | "base"
    straight_free: bool
    label: str


def workload_runs(seed: int, cleaning_runs: int) -> list[CleaningRun]:
    """Cleaning runs (each with its own door angles) and a door sweep at 0°, 45° and 90°."""
    runs = [cleaning_run(seed + k) for k in range(cleaning_runs)]
    return runs + [door_sweep_run(d, seed) for d in SWEEP_DOORS_DEG]


def build_pairs(
    model: RobotModel, count: int, seed: int, detour_share: float, cleaning_runs: int
) -> tuple[list[Pair], dict[str, Scene]]:
    """`count` planning calls of the workload; up to `detour_share` of them need a detour."""
    pools: dict[bool, list[Pair]] = {True: [], False: []}
    scenes: dict[str, Scene] = {}
    for run in workload_runs(seed, cleaning_runs):
        for call in run.calls:
            scene = run.scene_for(call)
            scenes[scene.hash] = scene
            start, goal = call.start.tolist(), call.goal.tolist()
            free = _straight_free(model, scene, start, goal)
            kind = "base" if call.base_moves else "arm"
            pools[free].append(Pair(scene.hash, tuple(start), tuple(goal), kind, free, call.label))
    rng = np.random.default_rng(seed)
    n_detour = min(len(pools[False]), round(count * detour_share))
    pairs: list[Pair] = []
    for free, n in ((False, n_detour), (True, count - n_detour)):
        pool = pools[free]
        pairs += [pool[k] for k in sorted(rng.choice(len(pool), min(n, len(pool)), False))]
    used = {p.scene for p in pairs}
    return pairs, {h: s for h, s in scenes.items() if h in used}


def _straight_free(model: RobotModel, scene: Scene, start: list[float], goal: list[float]) -> bool:
    a, b = np.array(start), np.array(goal)
    spec = state_space_spec(model, scene, around=(a, b))
    return MotionChecker(spec, scene).segment_free(a, b)


def run_pairs(
    pairs: list[Pair], planner: str, model: RobotModel, scenes: dict[str, Scene]
) -> list[PlanResult]:
    """Plan every pair with one planner ("naive" = the per-state OMPL baseline)."""
    source = ModelSource(
        model_id=model.model_id,
        urdf=reference_urdf(),
        base=model.base.value,
        joint_names=model.joint_names,
    )
    sources = {h: SceneSource(h, scene_to_payload(s)) for h, s in scenes.items()}
    results = []
    for seed, pair in enumerate(pairs):
        if planner == "naive":
            options = SearchOptions(budget_s=BUDGET_S, seed=seed)
            result = plan_ompl(
                model, scenes[pair.scene], pair.start, pair.goal, options, naive=True
            )
        else:
            problem = PlanningProblem(
                source, sources[pair.scene], pair.start, pair.goal,
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


def parse_args() -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="10 pairs")
    parser.add_argument("--pairs", type=int, default=120)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument(
        "--detour-share",
        type=float,
        default=0.5,
        help="share of calls whose straight segment collides (the workload itself has ~1%%)",
    )
    parser.add_argument("--cleaning-runs", type=int, default=20, help="runs to draw calls from")
    return parser.parse_args()


def run_planners(
    pairs: list[Pair], model: RobotModel, scenes: dict[str, Scene]
) -> dict[str, dict[str, float]]:
    """Each planner over all pairs: its summary, wall time and median on detour pairs."""
    summary: dict[str, dict[str, float]] = {}
    for planner in ("compiled", "rrtconnect", "rris", "naive"):
        t = time.perf_counter()
        results = run_pairs(pairs, planner, model, scenes)
        summary[planner] = summarize(results)
        summary[planner]["wall_s"] = time.perf_counter() - t
        detour = [r for r, p in zip(results, pairs, strict=True) if not p.straight_free]
        summary[planner]["detour_median_ms"] = (
            float(np.median([r.stats.get("plan_ms", 0.0) for r in detour])) if detour else 0.0
        )
        failures = [r for r in results if not r.solved]
        for r in failures[:3]:
            print(f"  {planner} failure: {r.status.value}: {r.message[:120]}")
    return summary


def print_table(summary: dict[str, dict[str, float]]) -> None:
    """One row per planner."""
    header = (
        f"{'planner':<11}{'success':>8}{'plan med':>10}{'plan p95':>10}{'total med':>11}"
        f"{'total p95':>11}{'len raw':>9}{'len short':>10}{'states':>8}{'calls':>7}{'fcl':>7}"
        f"{'detour med':>11}{'wall s':>8}"
    )
    print(header)
    print("-" * len(header))
    for planner, s in summary.items():
        print(
            f"{planner:<11}{s['success_rate']:>8.3f}{s['median_ms']:>10.1f}{s['p95_ms']:>10.1f}"
            f"{s['median_total_ms']:>11.1f}{s['p95_total_ms']:>11.1f}{s['length_before']:>9.2f}"
            f"{s['length_after']:>10.2f}{s['checks']:>8.0f}{s['check_calls']:>7.0f}"
            f"{s['narrow_checks']:>7.0f}{s['detour_median_ms']:>11.1f}{s['wall_s']:>8.1f}"
        )


def main() -> None:
    """Build the pairs, run the three planners, print a table and one JSON line."""
    args = parse_args()
    count = 10 if args.smoke else max(100, args.pairs)
    began = time.perf_counter()
    model = reference_model()
    runs = 2 if args.smoke else args.cleaning_runs
    pairs, scenes = build_pairs(model, count, args.seed, args.detour_share, runs)
    kinds = {k: sum(p.kind == k for p in pairs) for k in ("arm", "base")}
    straight = sum(p.straight_free for p in pairs)
    print(
        f"pairs: {len(pairs)} planning calls of the reference workload (seed {args.seed}: "
        f"cleaning runs {args.seed}..{args.seed + runs - 1}, door sweep {SWEEP_DOORS_DEG}°); "
        f"{kinds['arm']} arm, {kinds['base']} base; {straight} straight-line free; "
        f"{len(scenes)} scenes; built in {time.perf_counter() - began:.1f} s"
    )
    summary = run_planners(pairs, model, scenes)
    print_table(summary)
    ours, rris, naive = summary["rrtconnect"], summary["rris"], summary["naive"]
    compiled = summary["compiled"]
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
        "detour_median_ms": round(ours["detour_median_ms"], 2),
        "naive_detour_median_ms": round(naive["detour_median_ms"], 2),
        "compiled_success_rate": round(compiled["success_rate"], 4),
        "compiled_median_ms": round(compiled["median_ms"], 2),
        "compiled_p95_ms": round(compiled["p95_ms"], 2),
        "compiled_median_total_ms": round(compiled["median_total_ms"], 2),
        "compiled_detour_median_ms": round(compiled["detour_median_ms"], 2),
        "pairs": len(pairs),
        "straight_free_pairs": straight,
        "budget_s": BUDGET_S,
    }
    print(json.dumps(line))


if __name__ == "__main__":
    main()
