"""Load: N simulated robots against two service replicas on one PostgreSQL database.

Starts `--replicas` `trajcache serve` processes on a fresh schema of the PostgreSQL server
(`--database-url`) and drives them with the reference workload (REFERENCE.md): the reference
robot in the restroom.

- Warm cache: cleaning run S is played once through the service (its calls split over two
  warm-up robots, one per replica), so the planner fills the cache.
- Robots: robot k (`load-k`, spread round-robin over the replicas) replays cleaning run S+1+k:
  its own execution noise and door angles, so its scene is never one a trajectory was planned
  in and every hit is validated. Before each call it brings its scene up to date (PUT, then
  PATCH of what changed), as a robot controller does.
- Misses: about `--miss-share` of the calls are replaced by a novel request that no cached
  trajectory serves: an arm move of the run with start and goal each moved off by 0.22-0.4 rad
  on three random joints (beyond the lookup threshold of 0.2), within limits and collision-free
  in the scene in force, so the planner must solve it.
- Pace: each robot asks for its next plan when its slot comes (the robots together offer
  `--rate` plans per second; a robot executes one trajectory before it asks for the next).
  Latency is measured from the slot, so a server that falls behind shows it. `--rate 0` sends
  each robot's next request as soon as the previous one is answered (capacity).

The client is one asyncio process (uvloop when installed) with one keep-alive HTTP/1.1
connection per robot over plain streams and pre-encoded bodies: it shares the machine with the
replicas, so it spends as little CPU per request as it can.

Reported: plans per second, latency p50 and p99 (all plans, and hits and misses apart), errors
(a non-2xx answer, a transport error, a plan without a trajectory or a scene hash the service
did not confirm), the share of plans served from the cache, server and client CPU per plan.
Afterwards every trajectory a response said the planner stored (source "planner" with a
trajectory id) is looked up in the schema's `trajectories` table and read through the replica
that did not plan it; one missing from either is `lost`. The last line printed is one JSON
object with `plans_per_s`, `p50_ms`, `p99_ms`, `errors`, `lost`, `hit_share`, `robots` and
`replicas`.

    python bench/load.py [--smoke] [--robots 64] [--duration 30] [--rate 320] [--workers 1]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import threading
import time
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any

import sqlalchemy as sa

from harness.caches import fresh_schema
from harness.replay import RobotClient, register_reference_model
from harness.report import pct, print_measures
from harness.service import running_service, server_cpu_seconds
from load_drive import Outcome, Robot, Tally, install_event_loop_policy, run_load
from load_scripts import PLAN_OPTIONS, MissMaker, robot_script
from trajcache.reference.cleaning import CleaningRun, cleaning_run
from trajcache.reference.robot import reference_model
from trajcache_client import NO_RETRY, APIError, Client

POSTGRES_URL = os.environ.get(
    "TRAJCACHE_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test"
)
CAPACITY_GUESS = 800.0  # plans/s, to size the scripts of robots that do not wait (--rate 0)


# --- setup and the check afterwards --------------------------------------------------------


def warm_cache(bases: list[str], model_id: str, run: CleaningRun, calls: int | None) -> int:
    """Play the first `calls` calls of `run` with fallback planning; trajectories planned."""
    played = run.calls[:calls]
    halves = [played[: len(played) // 2], played[len(played) // 2 :]]
    planned = [0, 0]
    failures: list[str] = []

    def play(k: int) -> None:
        with Client(bases[k % len(bases)], timeout=120, retry=NO_RETRY) as client:
            robot = RobotClient(client, f"warm-{k}", model_id, "sim")
            try:
                for call in halves[k]:
                    planned[k] += robot.call(run, call, PLAN_OPTIONS).planned
            except Exception as exc:  # reported below
                failures.append(str(exc))

    threads = [threading.Thread(target=play, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if failures:
        raise RuntimeError(f"warm-up failed: {failures[0][:400]}")
    return sum(planned)


def register_robots(base: str, model_id: str, count: int) -> None:
    """Create robots load-0 … load-(count-1)."""
    with Client(base, timeout=60, retry=NO_RETRY) as client:
        for k in range(count):
            client.put_robot(f"load-{k}", model_id, kind="sim")


def _served(client: Client, trajectory_id: int) -> bool:
    """Whether the service of `client` answers GET /v1/trajectories/{trajectory_id} with 200."""
    try:
        client.get_trajectory(trajectory_id)
    except APIError:
        return False
    return True


def lost_trajectories(url: str, bases: list[str], plans: list[Outcome]) -> tuple[int, int]:
    """(planned trajectories answered, how many of them are missing) in the database or
    through the other replica."""
    planned = {(o.trajectory_id, o.replica) for o in plans if o.source == "planner"}
    ids = sorted({tid for tid, _ in planned if tid is not None})
    missing = sum(1 for tid, _ in planned if tid is None)
    engine = sa.create_engine(url)
    try:
        with engine.connect() as conn:
            stored = set(
                conn.execute(
                    sa.text("SELECT id FROM trajectories WHERE id = ANY(:ids)"), {"ids": ids}
                ).scalars()
            )
    finally:
        engine.dispose()
    missing += len(set(ids) - stored)
    clients = [Client(b, timeout=30, retry=NO_RETRY) for b in bases]
    try:
        for tid, replica in sorted(p for p in planned if p[0] is not None):
            other = clients[(replica + 1) % len(clients)]
            if tid is not None and tid in stored and not _served(other, tid):
                missing += 1
    finally:
        for client in clients:
            client.close()
    return len(ids), missing


@dataclass
class Measured:
    """What one run observed: the robots' tally and the figures taken around it."""

    tally: Tally
    elapsed: float  # s the robots were driven
    warmed: int  # trajectories planned in warm-up
    client_cpu: float  # s
    server_cpu: float  # s, all replicas
    planned: int  # planned trajectories checked afterwards
    lost: int


# --- the run --------------------------------------------------------------------------------


def parse_args() -> argparse.Namespace:
    """The command line, with the smoke run's defaults filled in."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--smoke", action="store_true", help="a few seconds, few robots (CI)")
    parser.add_argument("--robots", type=int, default=None, help="default 64 (smoke: 8)")
    parser.add_argument("--duration", type=float, default=None, help="seconds (default 30)")
    parser.add_argument("--rate", type=float, default=None, help="plans/s offered, 0: at once")
    parser.add_argument("--replicas", type=int, default=2)
    parser.add_argument("--workers", type=int, default=1, help="uvicorn workers per replica")
    parser.add_argument("--miss-share", type=float, default=0.1)
    parser.add_argument("--database-url", default=POSTGRES_URL, help="a PostgreSQL server")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    args.robots = args.robots or (8 if args.smoke else 64)
    args.duration = args.duration or (4.0 if args.smoke else 30.0)
    if args.rate is None:
        args.rate = 80.0 if args.smoke else 320.0
    args.calls = 60 if args.smoke else None  # calls per run played
    return args


def build_robots(args: argparse.Namespace) -> list[Robot]:
    """The robots and their scripts, long enough for the run (they repeat if the guess is short)."""
    misses = MissMaker(reference_model(), args.seed)
    per_run = len(cleaning_run(args.seed).calls[: args.calls])
    expected = (args.rate or CAPACITY_GUESS) * args.duration / args.robots  # plans per robot
    runs = int(expected * 1.5 // per_run) + 1
    return [
        Robot(
            f"load-{k}",
            k % args.replicas,
            robot_script(
                f"load-{k}",
                [cleaning_run(args.seed + 1 + k + j * args.robots) for j in range(runs)],
                args.calls,
                misses,
                args.miss_share,
            ),
        )
        for k in range(args.robots)
    ]


def measure(args: argparse.Namespace, robots: list[Robot]) -> Measured:
    """Start the replicas, warm the cache, drive the robots and check what they planned."""
    with ExitStack() as stack:
        url = stack.enter_context(fresh_schema(args.database_url))
        assert url is not None
        env = {"TRAJCACHE_AUTH_MODE": "off"}
        bases = [
            stack.enter_context(running_service(url, workers=args.workers, env=env))
            for _ in range(args.replicas)
        ]
        with Client(bases[0], timeout=60, retry=NO_RETRY) as client:
            model_id = register_reference_model(client)
        warmed = warm_cache(bases, model_id, cleaning_run(args.seed), args.calls)
        register_robots(bases[0], model_id, args.robots)
        cpu = [server_cpu_seconds(b) for b in bases]
        client_cpu = time.process_time()
        tally, elapsed = asyncio.run(
            run_load(robots, bases, duration_s=args.duration, rate=args.rate)
        )
        client_cpu = time.process_time() - client_cpu
        server_cpu = sum(server_cpu_seconds(b) - c for b, c in zip(bases, cpu, strict=True))
        planned, lost = lost_trajectories(url, bases, tally.plans)
    return Measured(tally, elapsed, warmed, client_cpu, server_cpu, planned, lost)


def summarize(args: argparse.Namespace, run: Measured) -> dict[str, Any]:
    """The final JSON line's figures."""
    tally = run.tally
    plans = tally.plans
    answered = [o for o in plans if o.ok]
    hits = [o.latency_ms for o in answered if o.source == "cache"]
    fresh = [o.latency_ms for o in answered if o.source == "planner"]
    every = [o.latency_ms for o in plans]
    n = max(len(plans), 1)

    def server_ms(source: str, key: str) -> float:
        values = [o.timings.get(key, 0.0) for o in answered if o.source == source]
        return round(statistics.median(values), 3) if values else float("nan")

    return {
        "plans_per_s": round(len(plans) / run.elapsed, 1),
        "p50_ms": round(pct(every, 50), 3),
        "p99_ms": round(pct(every, 99), 3),
        "errors": len(tally.errors),
        "lost": run.lost,
        "hit_share": round(len(hits) / n, 4),
        "robots": args.robots,
        "replicas": args.replicas,
        "plans": len(plans),
        "planned": run.planned,
        "hit_p50_ms": round(pct(hits, 50), 3),
        "hit_p99_ms": round(pct(hits, 99), 3),
        "miss_p50_ms": round(pct(fresh, 50), 3),
        "miss_p99_ms": round(pct(fresh, 99), 3),
        "hit_server_total_ms": server_ms("cache", "total"),
        "miss_server_total_ms": server_ms("planner", "total"),
        "miss_server_plan_ms": server_ms("planner", "plan"),
        "scene_updates": tally.scene_updates,
        "offered_rate": args.rate,
        "duration_s": round(run.elapsed, 2),
        "server_cpu_ms_per_plan": round(run.server_cpu / n * 1e3, 3),
        "client_cpu_ms_per_plan": round(run.client_cpu / n * 1e3, 3),
        "warm_trajectories": run.warmed,
        "workers": args.workers,
        "smoke": args.smoke,
    }


def print_table(summary: dict[str, Any], errors: list[str]) -> None:
    """The figures as a two-column table, then the first errors."""
    s = summary
    rate = s["offered_rate"]
    rows: list[tuple[str, object]] = [
        ("robots / replicas", f"{s['robots']} / {s['replicas']}"),
        ("offered plans/s", "as fast as answered" if rate <= 0 else rate),
        ("trajectories planned in warm-up", s["warm_trajectories"]),
        ("plans", s["plans"]),
        ("plans/s", s["plans_per_s"]),
        ("p50 ms", s["p50_ms"]),
        ("p99 ms", s["p99_ms"]),
        ("hit share", s["hit_share"]),
        ("hits p50 / p99 ms", f"{s['hit_p50_ms']} / {s['hit_p99_ms']}"),
        ("planned p50 / p99 ms", f"{s['miss_p50_ms']} / {s['miss_p99_ms']}"),
        (
            "server total p50 ms: hit / planned",
            f"{s['hit_server_total_ms']} / {s['miss_server_total_ms']}",
        ),
        ("  of which planner p50 ms", s["miss_server_plan_ms"]),
        ("scene updates", s["scene_updates"]),
        ("errors", s["errors"]),
        ("planned trajectories checked", s["planned"]),
        ("lost", s["lost"]),
        ("server CPU per plan ms", s["server_cpu_ms_per_plan"]),
        ("client CPU per plan ms", s["client_cpu_ms_per_plan"]),
    ]
    print_measures(rows, 34, 22)
    for error in errors[:5]:
        print(f"error: {error[:300]}")


def main() -> None:
    """Run the load and print the table and the JSON line."""
    args = parse_args()
    install_event_loop_policy()
    robots = build_robots(args)
    run = measure(args, robots)
    summary = summarize(args, run)
    print_table(summary, run.tally.errors)
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
