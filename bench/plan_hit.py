"""End-to-end cache-hit latency of POST /v1/robots/{id}/plan through the real service.

Starts `trajcache serve` (uvicorn on loopback; SQLite by default, or a fresh schema on the
PostgreSQL server given with --database-url) and drives it with the reference workload
(REFERENCE.md): the reference robot in the restroom.

- Warm cache: every call of cleaning run 1 (seed S) is planned in this process with the
  project's planner (OMPL RRTConnect, shortcut, certified-validated) in the scene in force at that
  call, and stored through the API as `sim`, which is what pre-seeding does.
- Queries: the calls of further runs (seeds S+1, S+2, …). Every call carries fresh execution
  noise, and the doors start and open at other angles than in run 1, so the robot's scene is
  never the one a trajectory was planned in. Each distinct scene of those runs is uploaded once,
  as its own robot, and every query goes to the robot whose scene it was made in. Before timing,
  each robot answers one request of an unrelated run (its validator is built, as it would be
  after the first call that follows a scene change).
- Sequential: one keep-alive connection per client library sends each query once, in run order,
  the two taking turns: a lean client (the standard library's http.client, as any compiled
  robot-side HTTP client is at least as lean) and the Python client package (trajcache_client,
  over httpx; it spends about 0.4 ms more CPU per request on the client side). No request
  repeats, so every answer is validated against the scene (the validation memo only helps
  where a cached interior recurs exactly). Latency percentiles are over the answers served
  from the cache; misses are counted, not timed. `p50_ms` and `p99_ms` are the lean client's,
  `httpx_p50_ms` and `httpx_p99_ms` the Python client's.
- Repeat: the same sequential requests once more. Exact repeats are answered from the validation
  memo without collision checks: the most the memo can give, not what a robot sees.
- Concurrent: 16 clients, each sending its own share of further fresh queries; plans per second
  over all requests.

Server-side breakdown: `timings_ms` (db, lookup, validate, total of the plan flow) and the
`Server-Timing` header (answer extras such as quality metrics, serialize); "http" is client
latency minus all of those, and GET /healthz with the same clients shows the transport and
framework floor. The last line printed is one JSON object with `p50_ms`, `p99_ms` and
`concurrent_rps`. Server CPU per plan (the service's processes, from /proc) is reported too:
unlike latency, it hardly moves when other programs load the machine.

    python bench/plan_hit.py [--smoke] [--database-url postgresql+psycopg://…] [--workers N]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import statistics
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from harness.caches import fresh_schema
from harness.report import pct, print_measures
from harness.service import running_service, server_cpu_seconds
from plan_hit_clients import (
    CONCURRENCY,
    Query,
    Sample,
    api_client,
    http_floor,
    run_both,
    run_concurrent,
    run_sequential,
)
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.planning.problem import ModelSource, PlanningProblem, SceneSource
from trajcache.planning.run import run_planning
from trajcache.reference.cleaning import CleaningRun, cleaning_run
from trajcache.reference.robot import reference_model, reference_urdf
from trajcache_client import APIError, Client

QUERY_DOORS_START = (4.0, 11.0, 17.0)  # degrees per stall; run 1 draws its own
QUERY_DOORS_OPEN = 83.0
PLAN_OPTIONS = {"fallback": False}


def fill_cache(client: Client, model_id: str, run: CleaningRun, calls: int) -> int:
    """Plan the first `calls` calls of `run` in its scenes and store them; return how many."""
    model = reference_model()
    source = ModelSource(
        model_id=model_id,
        urdf=reference_urdf(),
        base="planar",
        joint_names=tuple(model.state_names[3:]),
    )
    stored = 0
    for call in run.calls[:calls]:
        scene = run.scene_for(call)
        problem = PlanningProblem(
            model=source,
            scene=SceneSource(scene.hash, scene_to_payload(scene)),
            start=tuple(call.start),
            goal=tuple(call.goal),
            seed=call.index,
        )
        result = run_planning(problem)
        if not result.solved or result.path is None:
            continue
        client.store_trajectory(
            model_id,
            result.path.tolist(),
            source="sim",
            scene_hash=scene.hash,
            env=dict(scene.env),
        )
        stored += 1
    return stored


class Robots:
    """One robot per distinct scene, created (and its scene uploaded) on first use."""

    def __init__(self, client: Client, model_id: str) -> None:
        self.client, self.model_id = client, model_id
        self.by_hash: dict[str, str] = {}

    def robot_for(self, scene: Scene) -> str:
        """The id of the robot whose scene is `scene`."""
        robot_id = self.by_hash.get(scene.hash)
        if robot_id is None:
            robot_id = f"bench-{len(self.by_hash)}"
            with contextlib.suppress(APIError):  # as before: a refusal shows at the scene
                self.client.put_robot(robot_id, self.model_id)
            self.client.put_scene(robot_id, scene_to_payload(scene))
            self.by_hash[scene.hash] = robot_id
        return robot_id


def query_run(seed: int, calls: int, robots: Robots) -> list[Query]:
    """The first `calls` calls of a query run as requests."""
    run = cleaning_run(
        seed,
        initial_doors_deg=QUERY_DOORS_START,
        door_open_deg=(QUERY_DOORS_OPEN, QUERY_DOORS_OPEN),
    )
    return [
        Query(
            robots.robot_for(run.scene_for(call)),
            {"start": call.start.tolist(), "goal": call.goal.tolist(), "options": PLAN_OPTIONS},
        )
        for call in run.calls[:calls]
    ]


def _timed(query: Query) -> Query:
    """The same request asking for a toppra-timed JointTrajectory."""
    base = query.body["options"]
    assert isinstance(base, dict)
    options = {**base, "timing": {"method": "toppra"}}
    return Query(query.robot_id, {**query.body, "options": options})


@contextmanager
def database(url: str | None) -> Iterator[str | None]:
    """`url` as given (None: the service's temporary SQLite), or a fresh PostgreSQL schema."""
    if url is None or not url.startswith("postgresql"):
        yield url
        return
    with fresh_schema(url) as schema_url:
        yield schema_url


def summarize(samples: list[Sample]) -> dict[str, float]:
    """Latency percentiles and the median server breakdown of the cache hits."""
    hits = [s for s in samples if s.hit]
    if not hits:
        return {"hits": 0}

    def med(key: str) -> float:
        return statistics.median(s.timings.get(key, 0.0) for s in hits)

    http = [s.latency_ms - s.timings.get("total", 0.0) - s.extras_ms - s.serialize_ms for s in hits]
    return {
        "hits": len(hits),
        "p50": pct([s.latency_ms for s in hits], 50),
        "p99": pct([s.latency_ms for s in hits], 99),
        "db": med("db"),
        "lookup": med("lookup"),
        "validate": med("validate"),
        "total": med("total"),
        "total_p99": pct([s.timings.get("total", 0.0) for s in hits], 99),
        "extras": statistics.median(s.extras_ms for s in hits),
        "serialize": statistics.median(s.serialize_ms for s in hits),
        "http": statistics.median(http),
    }


@dataclass
class Workload:
    """The cache filled from run 1, and the queries of the further runs."""

    stored: int  # trajectories cached
    robots: Robots
    queries: list[Query]  # sequential ones first, then the concurrent ones
    warmup: list[Query]  # one per robot, of an unrelated run


@dataclass
class Measured:
    """What the service answered in each phase."""

    sequential: int
    concurrent: int
    floor: float  # GET /healthz p50 ms, http.client
    floor_httpx: float  # … and trajcache_client
    first: list[Sample]  # fresh sequential queries, http.client
    first_httpx: list[Sample]  # … and trajcache_client
    again: list[Sample]  # the same queries repeated
    timed: list[Sample]  # … repeated asking for toppra timing
    cpu_seq: float  # server CPU ms per plan
    rps: float
    conc_hits: int
    cpu_conc: float


def parse_args() -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--smoke", action="store_true", help="small run for CI")
    parser.add_argument("--database-url", default=None, help="default: a temporary SQLite file")
    parser.add_argument("--workers", type=int, default=1, help="server worker processes")
    parser.add_argument("--seed", type=int, default=1)
    return parser.parse_args()


def prepare(base: str, seed: int, calls: int | None, wanted: int) -> Workload:
    """Register the model, fill the cache from run `seed` and make `wanted` queries or more."""
    fill_run = cleaning_run(seed)
    per_run = len(fill_run.calls[:calls])
    with api_client(base, 60) as client:
        model = client.register_model(reference_urdf(), base="planar", name="xarm7-mobile")
        model_id = model.model_id
        stored = fill_cache(client, model_id, fill_run, per_run)
        robots = Robots(client, model_id)
        runs = -(-wanted // per_run) + 1
        queries = [q for k in range(1, runs + 1) for q in query_run(seed + k, per_run, robots)]
        warmup = {q.robot_id: q for q in query_run(seed + 10_000, per_run, robots)}
    return Workload(stored, robots, queries, list(warmup.values()))


def measure(base: str, workload: Workload, sequential: int, concurrent: int) -> Measured:
    """Warm each robot's validator, then time the sequential, repeated and concurrent phases."""
    run_sequential(base, workload.warmup)
    seq_queries = workload.queries[:sequential]
    conc_queries = workload.queries[sequential:][:concurrent]
    floor, floor_httpx = http_floor(base)
    cpu = server_cpu_seconds(base)
    first, first_httpx = run_both(base, seq_queries)
    cpu_seq = (server_cpu_seconds(base) - cpu) / len(seq_queries) * 1e3
    again, _ = run_both(base, seq_queries)
    timed, _ = run_both(base, [_timed(q) for q in seq_queries])
    cpu = server_cpu_seconds(base)
    rps, conc_hits = run_concurrent(base, conc_queries)
    cpu_conc = (server_cpu_seconds(base) - cpu) / len(conc_queries) * 1e3
    return Measured(
        len(seq_queries),
        len(conc_queries),
        floor,
        floor_httpx,
        first,
        first_httpx,
        again,
        timed,
        cpu_seq,
        rps,
        conc_hits,
        cpu_conc,
    )


def print_table(workload: Workload, m: Measured) -> None:
    """The figures as a two-column table."""
    fresh, fresh_httpx = summarize(m.first), summarize(m.first_httpx)
    repeat, timed_repeat = summarize(m.again), summarize(m.timed)
    timing_cost = timed_repeat.get("p50", float("nan")) - repeat.get("p50", float("nan"))
    rows: list[tuple[str, object]] = [
        ("trajectories cached (run 1)", workload.stored),
        ("scenes (robots)", len(workload.robots.by_hash)),
        ("sequential requests", m.sequential),
        ("cache hits", fresh["hits"] + fresh_httpx["hits"]),
        ("client p50 ms (http.client)", fresh.get("p50")),
        ("client p99 ms (http.client)", fresh.get("p99")),
        ("client p50 ms (trajcache_client)", fresh_httpx.get("p50")),
        ("client p99 ms (trajcache_client)", fresh_httpx.get("p99")),
        ("server db p50 ms", fresh.get("db")),
        ("server lookup p50 ms", fresh.get("lookup")),
        ("server validate p50 ms", fresh.get("validate")),
        ("server total p50 ms", fresh.get("total")),
        ("server total p99 ms", fresh.get("total_p99")),
        ("answer extras (quality) p50 ms", fresh.get("extras")),
        ("server serialize p50 ms", fresh.get("serialize")),
        ("http p50 ms (http.client)", fresh.get("http")),
        ("http floor: GET /healthz p50 ms", m.floor),
        ("http floor: GET /healthz p50 ms (trajcache_client)", m.floor_httpx),
        ("server CPU per plan, sequential ms", m.cpu_seq),
        ("repeat: client p50 ms", repeat.get("p50")),
        ("repeat: client p99 ms", repeat.get("p99")),
        ("repeat: server validate p50 ms", repeat.get("validate")),
        ("timed repeat (toppra): client p50 ms", timed_repeat.get("p50")),
        ("added p50 ms for timing", timing_cost),
        (f"concurrent rps ({CONCURRENCY} clients)", m.rps),
        ("concurrent hit rate", m.conc_hits / max(m.concurrent, 1)),
        ("server CPU per plan, concurrent ms", m.cpu_conc),
    ]
    print_measures(rows, 36, 10)


def summary_line(args: argparse.Namespace, url: str | None, m: Measured) -> dict[str, Any]:
    """The final JSON line's figures."""
    nan = float("nan")
    fresh, fresh_httpx = summarize(m.first), summarize(m.first_httpx)
    repeat, timed_repeat = summarize(m.again), summarize(m.timed)
    timing_cost = timed_repeat.get("p50", nan) - repeat.get("p50", nan)
    return {
        "p50_ms": round(fresh.get("p50", nan), 3),
        "p99_ms": round(fresh.get("p99", nan), 3),
        "concurrent_rps": round(m.rps, 1),
        "httpx_p50_ms": round(fresh_httpx.get("p50", nan), 3),
        "httpx_p99_ms": round(fresh_httpx.get("p99", nan), 3),
        "hit_rate": round((fresh["hits"] + fresh_httpx["hits"]) / max(m.sequential, 1), 4),
        "repeat_p50_ms": round(repeat.get("p50", nan), 3),
        "repeat_p99_ms": round(repeat.get("p99", nan), 3),
        "timed_repeat_p50_ms": round(timed_repeat.get("p50", nan), 3),
        "timing_added_p50_ms": round(timing_cost, 3),
        "server_db_ms": round(fresh.get("db", nan), 3),
        "server_lookup_ms": round(fresh.get("lookup", nan), 3),
        "server_validate_ms": round(fresh.get("validate", nan), 3),
        "server_total_ms": round(fresh.get("total", nan), 3),
        "server_total_p99_ms": round(fresh.get("total_p99", nan), 3),
        "server_extras_ms": round(fresh.get("extras", nan), 3),
        "server_serialize_ms": round(fresh.get("serialize", nan), 3),
        "http_ms": round(fresh.get("http", nan), 3),
        "healthz_ms": round(m.floor, 3),
        "httpx_healthz_ms": round(m.floor_httpx, 3),
        "server_cpu_ms_sequential": round(m.cpu_seq, 3),
        "server_cpu_ms_concurrent": round(m.cpu_conc, 3),
        "database": "postgresql" if url and url.startswith("postgresql") else "sqlite",
        "workers": args.workers,
        "smoke": args.smoke,
    }


def main() -> None:
    """Run the benchmark and print the table and the JSON line."""
    args = parse_args()
    calls, sequential, concurrent = (40, 60, 160) if args.smoke else (None, 600, 3200)
    with database(args.database_url) as url, running_service(url, workers=args.workers) as base:
        workload = prepare(base, args.seed, calls, sequential + concurrent)
        measured = measure(base, workload, sequential, concurrent)
    print_table(workload, measured)
    print(json.dumps(summary_line(args, url, measured)))


if __name__ == "__main__":
    main()
