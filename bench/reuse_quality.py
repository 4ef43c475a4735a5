"""Reuse quality: how good is a cached (adapted) trajectory compared with a fresh plan?

Starts `trajcache serve` (SQLite by default), registers the reference robot and runs two cleaning
runs of the reference workload (REFERENCE.md) through POST /v1/robots/{id}/plan, uploading the
scene in force before each call: run 1 fills the cache, run 2 is served from it. Every answer asks
for full quality and toppra timing. For each cache hit the same query is also planned fresh
in-process (`run_planning`, the service's default planner and budget) and measured with the same
functions, in the same scene: state-space path length, end-effector path length, minimum
clearance to the scene and duration after time-optimal timing. Ratios are cached / fresh (for
clearance higher is better; for the others lower is better), over all hits and over the hits
whose answer is not the fresh plan's path (most reference motions are one straight segment
either way).

Then the costs: toppra on each answered hit in-process, the server's `timing` time, every
metric of a fresh plan (what storing a trajectory adds), and the added client latency of a timed
cache hit (hits replayed with and without timing, interleaved).

    python bench/reuse_quality.py            # two full runs (~270 calls each)
    python bench/reuse_quality.py --smoke    # the first 30 calls of each run

The last line printed is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from harness.service import running_service
from trajcache.core.config import Settings
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.path_quality import Quality
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.planning.problem import ModelSource, PlanningProblem, SceneSource
from trajcache.planning.run import run_planning
from trajcache.reference.cleaning import CleaningRun, PlanCall, cleaning_run
from trajcache.reference.robot import REFERENCE_BASE, reference_model, reference_urdf
from trajcache.services.quality import TimingRequest, time_states, trajectory_quality
from trajcache.timing import TimingError
from trajcache_client import NO_RETRY, APIError, Client, PlanResult

ROBOT = "bench-reuse"
FAILURES: list[str] = []  # why fresh plans failed
STORE_QUALITY_MS: list[float] = []  # what every metric of a fresh plan costs (as at store time)
METRICS = ("path_length", "ee_path_length", "duration_s", "min_clearance")
LABELS = {
    "path_length": "path length (state space)",
    "ee_path_length": "end-effector path length",
    "duration_s": "duration (toppra)",
    "min_clearance": "min clearance (higher=better)",
}


@dataclass
class Hit:
    """One cache hit: the query, its scene, the answer's quality and the fresh plan's."""

    run: int
    call: PlanCall
    scene: Scene
    states: np.ndarray
    cached: dict[str, Any]
    fresh: Quality | None = None
    server_timing_ms: float = 0.0


def percentile(values: list[float], q: float) -> float:
    """The q-th percentile (0–100), NaN for no values."""
    return float(np.percentile(np.asarray(values), q)) if values else float("nan")


def _plan(
    client: Client, start: list[float], goal: list[float], options: dict[str, Any]
) -> PlanResult | None:
    """The answer to a plan request of the benchmark's robot; None for an error answer."""
    try:
        return client.plan(ROBOT, start, goal, options)
    except APIError:  # an error answer: neither a hit nor planned
        return None


def run_calls(
    client: Client, run_index: int, run: CleaningRun, calls: list[PlanCall]
) -> tuple[list[Hit], int, int]:
    """Send a run's calls (uploading each scene change); return the hits, planner and other."""
    hits: list[Hit] = []
    planned = other = 0
    current = None
    options = {"quality": "full", "timing": {"method": "toppra"}}
    for call in calls:
        scene = run.scene_for(call)
        if scene.hash != current:
            client.put_scene(ROBOT, scene_to_payload(scene))
            current = scene.hash
        answer = _plan(client, call.start.tolist(), call.goal.tolist(), options)
        if answer is not None and answer.source == "cache":
            assert answer.quality is not None  # every request asks for full quality
            timing_ms = float(answer.timings_ms.get("timing", 0.0))
            states = np.asarray(answer.states, dtype=float)
            quality = answer.quality.model_dump()
            hits.append(Hit(run_index, call, scene, states, quality, None, timing_ms))
        elif answer is not None and answer.source == "planner":
            planned += 1
        else:
            other += 1
    return hits, planned, other


def plan_fresh(
    model: RobotModel, source: ModelSource, hit: Hit, settings: Settings
) -> Quality | None:
    """Plan the hit's query from scratch as the service would; its quality, or None."""
    problem = PlanningProblem(
        model=source,
        scene=SceneSource(hash=hit.scene.hash, payload=scene_to_payload(hit.scene)),
        start=tuple(float(v) for v in hit.call.start),
        goal=tuple(float(v) for v in hit.call.goal),
        budget_s=settings.plan_budget_s,
        planner=settings.default_planner,
    )
    result = run_planning(problem)
    if not result.solved or result.path is None:
        FAILURES.append(f"{result.status.value}: {result.message}")
        return None
    began = time.perf_counter()
    quality, _ = trajectory_quality(model, result.path, settings, scene=hit.scene)
    STORE_QUALITY_MS.append((time.perf_counter() - began) * 1e3)
    return quality


def _same_path(hit: Hit) -> bool:
    """Whether the cached answer and the fresh plan have the same length (both straight, say)."""
    fresh = hit.fresh.path_length if hit.fresh is not None else None
    return fresh is not None and abs(hit.cached["path_length"] - fresh) <= 1e-9 * max(1.0, fresh)


def ratios(hits: list[Hit], metric: str) -> list[float]:
    """cached / fresh for every hit where both values exist and the fresh one is positive."""
    out = []
    for hit in hits:
        cached = hit.cached.get(metric)
        fresh = getattr(hit.fresh, metric) if hit.fresh is not None else None
        if cached is not None and fresh is not None and fresh > 1e-9:
            out.append(float(cached) / float(fresh))
    return out


def timing_cost_ms(
    model: RobotModel, hits: list[Hit], settings: Settings
) -> tuple[list[float], int]:
    """In-process time of default toppra timing of each answered hit (best of 3, ms), and how
    many hits toppra could not time."""
    costs = []
    failures = 0
    for hit in hits:
        best = float("inf")
        try:
            for _ in range(3):
                began = time.perf_counter()
                time_states(model, hit.states, settings, TimingRequest())
                best = min(best, (time.perf_counter() - began) * 1e3)
        except TimingError:
            failures += 1
            continue
        costs.append(best)
    return costs, failures


def replay_latency(client: Client, hits: list[Hit], rounds: int) -> tuple[list[float], list[float]]:
    """Client latency (ms) of the hits replayed without and with timing, interleaved."""
    plain: list[float] = []
    timed: list[float] = []
    current = None
    for hit in hits:
        if hit.scene.hash != current:
            client.put_scene(ROBOT, scene_to_payload(hit.scene))
            current = hit.scene.hash
        start, goal = hit.call.start.tolist(), hit.call.goal.tolist()
        for _ in range(rounds):
            for options, sink in (
                ({"fallback": False}, plain),
                ({"fallback": False, "timing": {"method": "toppra"}}, timed),
            ):
                began = time.perf_counter()
                answer = _plan(client, start, goal, options)
                elapsed = (time.perf_counter() - began) * 1e3
                if answer is not None and answer.source == "cache":
                    sink.append(elapsed)
    return plain, timed


@dataclass
class Collected:
    """The hits of the runs (with their fresh plans) and the latencies of replaying them."""

    hits: list[Hit]
    counts: list[tuple[int, int, int, int, int]]  # run, calls, hits, planned, other
    plain: list[float]  # client latency ms, untimed hits
    timed: list[float]  # … asking for timing


def collect(args: argparse.Namespace, model: RobotModel, settings: Settings) -> Collected:
    """Play two cleaning runs through the service, plan each hit afresh, replay the hits."""
    limit = 30 if args.smoke else None
    source = ModelSource(
        model_id=model.model_id,
        urdf=reference_urdf(),
        base=REFERENCE_BASE,
        joint_names=model.joint_names,
    )
    runs = [cleaning_run(args.seed), cleaning_run(args.seed + 1)]
    with (
        running_service(args.database_url) as base,
        Client(base, timeout=60, retry=NO_RETRY) as client,
    ):
        registered = client.register_model(
            reference_urdf(), base=REFERENCE_BASE, name="xarm7-mobile"
        )
        client.put_robot(ROBOT, registered.model_id)
        hits: list[Hit] = []
        counts = []
        for index, run in enumerate(runs, start=1):
            calls = run.calls[:limit]
            run_hits, planned, other = run_calls(client, index, run, calls)
            hits += run_hits
            counts.append((index, len(calls), len(run_hits), planned, other))
        for hit in hits:
            hit.fresh = plan_fresh(model, source, hit, settings)
        replayed = hits[: 20 if args.smoke else 100]
        replay_latency(client, replayed[:5], 1)  # warm-up
        plain, timed = replay_latency(client, replayed, 3 if args.smoke else 5)
    return Collected(hits, counts, plain, timed)


def print_ratios(compared: list[Hit], differ: list[Hit], summary: dict[str, Any]) -> None:
    """Cached / fresh ratios of each metric, for all compared hits and the differing paths."""
    for title, group in (("all compared hits", compared), ("paths unlike the fresh", differ)):
        print(f"\n{title} ({len(group)})")
        print(f"{'metric':<32}{'median':>9}{'p10':>9}{'p90':>9}{'min':>9}{'max':>9}")
        for metric in METRICS:
            values = ratios(group, metric)
            med, p10, p90 = (percentile(values, q) for q in (50, 10, 90))
            low = min(values, default=float("nan"))
            high = max(values, default=float("nan"))
            print(f"{LABELS[metric]:<32}{med:>9.3f}{p10:>9.3f}{p90:>9.3f}{low:>9.3f}{high:>9.3f}")
            key = metric.removesuffix("_s").replace("path_length", "length")
            key = key.replace("min_", "")
            if group is compared:
                summary[f"median_{key}_ratio"] = round(med, 4)
                summary[f"p90_{key}_ratio"] = round(p90, 4)
            elif metric in ("path_length", "duration_s"):
                summary[f"median_{key}_ratio_different_paths"] = round(med, 4)


def print_timing_costs(got: Collected, toppra_ms: list[float], server_ms: list[float]) -> float:
    """What timing a hit costs, in process, at the server and at the client; the added p50."""
    added = percentile(got.timed, 50) - percentile(got.plain, 50)
    print(f"\n{'timing cost (ms)':<40}{'p50':>9}{'p90':>9}")
    for label, values in (
        ("toppra in-process, per answered hit", toppra_ms),
        ("server 'timing' (toppra + sampling)", server_ms),
        ("all metrics of a plan (store time)", STORE_QUALITY_MS),
        ("client latency, untimed hit", got.plain),
        ("client latency, timed hit", got.timed),
    ):
        print(f"{label:<40}{percentile(values, 50):>9.2f}{percentile(values, 90):>9.2f}")
    print(f"{'added p50 latency of a timed hit':<40}{added:>9.2f}")
    return added


def main() -> None:
    """Run the benchmark and print the table and the JSON line."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--smoke", action="store_true", help="30 calls per run, for CI")
    parser.add_argument("--database-url", default=None, help="default: a temporary SQLite file")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    settings = Settings()
    model = reference_model()
    got = collect(args, model, settings)
    hits = got.hits
    compared = [h for h in hits if h.fresh is not None]
    toppra_ms, toppra_failures = timing_cost_ms(model, hits, settings)
    server_ms = [h.server_timing_ms for h in hits]

    print(f"{'run':<6}{'calls':>7}{'hits':>7}{'planned':>9}{'other':>7}")
    for index, calls_n, hits_n, planned, other in got.counts:
        print(f"{index:<6}{calls_n:>7}{hits_n:>7}{planned:>9}{other:>7}")
    print(f"\ncached / fresh, {len(compared)} hits (fresh plan failed: "
          f"{len(hits) - len(compared)})")  # fmt: skip
    if FAILURES:
        print(f"first fresh-plan failure: {FAILURES[0]}")
    differ = [h for h in compared if not _same_path(h)]
    summary: dict[str, Any] = {
        "hits": len(hits),
        "compared": len(compared),
        "different_paths": len(differ),
    }
    print_ratios(compared, differ, summary)
    added = print_timing_costs(got, toppra_ms, server_ms)
    plain, timed = got.plain, got.timed
    summary.update(
        {
            "toppra_ms_p50": round(percentile(toppra_ms, 50), 3),
            "toppra_failures": toppra_failures,
            "server_timing_ms_p50": round(percentile(server_ms, 50), 3),
            "store_quality_ms_p50": round(percentile(STORE_QUALITY_MS, 50), 3),
            "hit_latency_ms_p50": round(percentile(plain, 50), 3),
            "timed_hit_latency_ms_p50": round(percentile(timed, 50), 3),
            "timed_hit_added_ms_p50": round(added, 3),
        }
    )
    print(json.dumps({k: None if v != v else v for k, v in summary.items()}))  # NaN → null


if __name__ == "__main__":
    main()
