"""Pre-seeding through the API: the door sweep as seed jobs, then a "real robot" on a new scene.

The service is the real app (lifespan, migrations, background seed scheduler) on a fresh SQLite
file with the local planner pool (`--workers` processes), driven in-process over ASGI through
the Python client (trajcache_client); the cache size and plan-event sums are read from the
service's database.

1. Seed (REFERENCE.md, benchmark row 4): one seed job per door angle 0°, 10°, … 90°, each the
   reference door-sweep run at that angle (`POST /v1/seed-jobs` with workload `door_sweep`),
   one after the other into one cache. Per row: requests, cache hits, planned (stored as `sim`),
   failed, trajectories in the cache after it, time in lookup + validation and in the planner
   (sums over the job's plan events) and the job's wall time.
2. Real robot (row 5): a robot of kind `real` runs the perturbed cleaning run (fixtures shifted
   by up to 2 cm, doors between the seeded angles, execution noise ±3 cm / ±0.03 rad), uploading
   its scene when it changes and asking `POST /v1/robots/{id}/plan` for every call: (b) on an
   empty cache (a database of its own), (c) on the pre-seeded cache, (d) a second run on top of
   (c). Speed-up is the planning total of (b) over the row's.

The last line printed is one JSON object with every row.

    python bench/preseed.py            # full sweep: 10 × 271 calls, then 3 × 277 (minutes)
    python bench/preseed.py --smoke    # doors 0° and 90°, the first 30 calls of each run
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import sqlalchemy as sa
from fastapi.testclient import TestClient

from trajcache.core.config import Settings
from trajcache.db.models import PlanEvent, Trajectory
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.main import create_app
from trajcache.reference.cleaning import cleaning_run
from trajcache.reference.robot import reference_urdf
from trajcache.services.context import ServiceContext
from trajcache_client import NO_RETRY, APIError, Client

HEADER = (
    f"{'row':<28}{'calls':>6}{'hits':>6}{'plan':>6}{'fail':>6}{'cache':>7}"
    f"{'look+val s':>11}{'plan s':>8}{'total s':>9}{'wall s':>8}{'hit %':>7}"
)


class InProcessTransport(httpx.BaseTransport):
    """Sends each request through a running TestClient: the app in process, lifespan included."""

    def __init__(self, app: TestClient) -> None:
        self.app = app

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        """The app's answer to `request`, read whole."""
        answer = self.app.send(request)
        return httpx.Response(answer.status_code, headers=answer.headers, content=answer.content)


@dataclass(frozen=True)
class Service:
    """The app in process: a client of its API, and its context for the database counts."""

    api: Client
    ctx: ServiceContext


def _cache_size(service: Service) -> int:
    with service.ctx.sessions() as session:
        return int(session.scalar(sa.select(sa.func.count()).select_from(Trajectory)) or 0)


def _event_sums(service: Service, robot_id: str) -> dict[str, float]:
    ctx = service.ctx
    ctx.records.flush()
    with ctx.sessions() as session:
        row = session.execute(
            sa.select(
                sa.func.coalesce(sa.func.sum(PlanEvent.lookup_ms + PlanEvent.validate_ms), 0.0),
                sa.func.coalesce(sa.func.sum(PlanEvent.plan_ms), 0.0),
                sa.func.coalesce(sa.func.sum(PlanEvent.total_ms), 0.0),
            ).where(PlanEvent.robot_id == robot_id)
        ).one()
    return {"lookup_validate_s": row[0] / 1e3, "plan_s": row[1] / 1e3, "total_s": row[2] / 1e3}


def _print(row: dict[str, Any]) -> None:
    hit = 100.0 * row["hits"] / row["calls"] if row["calls"] else 0.0
    print(
        f"{row['row']:<28}{row['calls']:>6}{row['hits']:>6}{row['planned']:>6}{row['failed']:>6}"
        f"{row['cache']:>7}{row['lookup_validate_s']:>11.2f}{row['plan_s']:>8.2f}"
        f"{row['total_s']:>9.2f}{row['wall_s']:>8.1f}{hit:>7.1f}",
        flush=True,
    )


def seed_row(service: Service, model_id: str, door: float, seed: int, limit: int | None) -> dict:
    """One seed job: the door-sweep run at `door` degrees."""
    workload: dict[str, Any] = {"name": "door_sweep", "seed": seed, "doors_deg": [door]}
    if limit is not None:
        workload["limit"] = limit
    began = time.perf_counter()
    job = service.api.create_seed_job({"workload": workload}, model_id=model_id)
    while job.active:
        time.sleep(0.2)
        job = service.api.get_seed_job(job.job_id)
    wall = time.perf_counter() - began
    return {
        "row": f"seed job {job.job_id}: doors {door:g}°",
        "calls": job.total,
        "hits": job.hits,
        "planned": job.planned,
        "failed": job.failed,
        "cache": _cache_size(service),
        "wall_s": wall,
        **_event_sums(service, f"seed-job-{job.job_id}"),
    }


def real_row(service: Service, model_id: str, robot: str, seed: int, limit: int | None) -> dict:
    """The perturbed cleaning run by a `real` robot, every call through the plan endpoint."""
    client = service.api
    client.put_robot(robot, model_id, kind="real")
    run = cleaning_run(seed, perturbed=True)
    calls = run.calls[:limit]
    counts = {"hits": 0, "planned": 0, "failed": 0}
    current = None
    began = time.perf_counter()
    for call in calls:
        scene = run.scene_for(call)
        if scene.hash != current:
            client.put_scene(robot, scene_to_payload(scene))
            current = scene.hash
        try:
            answer = client.plan(robot, call.start.tolist(), call.goal.tolist())
        except APIError:
            counts["failed"] += 1
            continue
        if answer.status != "success":
            counts["failed"] += 1
        else:
            counts["hits" if answer.source == "cache" else "planned"] += 1
    wall = time.perf_counter() - began
    return {
        "row": robot,
        "calls": len(calls),
        **counts,
        "cache": _cache_size(service),
        "wall_s": wall,
        **_event_sums(service, robot),
    }


@contextmanager
def _app(url: str, workers: int) -> Iterator[Service]:
    """The app on the database `url`, running until the block ends."""
    settings = Settings(database_url=url, worker_processes=workers, seed_heartbeat_s=0.5)
    with TestClient(create_app(settings)) as app:
        transport = InProcessTransport(app)
        with Client(str(app.base_url), retry=NO_RETRY, transport=transport) as api:
            yield Service(api, app.app.state.ctx)  # type: ignore[attr-defined]


def _warm(service: Service) -> None:
    """Wait until the planner workers are up (a cold start would time out the first plans)."""
    pool = service.ctx.planner_pool()
    wait_ready = getattr(getattr(pool, "backend", None), "wait_ready", None)
    if callable(wait_ready):
        wait_ready(300.0)


def _register(service: Service) -> str:
    return service.api.register_model(reference_urdf(), base="planar").model_id


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--smoke", action="store_true", help="doors 0° and 90°, 30 calls each")
    parser.add_argument("--seed", type=int, default=1, help="seed of the door-sweep runs")
    parser.add_argument("--real-seed", type=int, default=7, help="seed of the real robot's run")
    parser.add_argument("--workers", type=int, default=2, help="local planner processes")
    args = parser.parse_args()
    doors = [0.0, 90.0] if args.smoke else [float(d) for d in range(0, 91, 10)]
    limit = 30 if args.smoke else None
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        print(HEADER, flush=True)
        with _app(f"sqlite:///{Path(tmp) / 'empty.db'}", args.workers) as empty:
            _warm(empty)
            rows.append(
                real_row(empty, _register(empty), "real-empty-cache", args.real_seed, limit)
            )
            _print(rows[-1])
        with _app(f"sqlite:///{Path(tmp) / 'seeded.db'}", args.workers) as service:
            _warm(service)
            model_id = _register(service)
            for door in doors:
                rows.append(seed_row(service, model_id, door, args.seed, limit))
                _print(rows[-1])
            for name in ("real-seeded-run-1", "real-seeded-run-2"):
                rows.append(real_row(service, model_id, name, args.real_seed, limit))
                _print(rows[-1])
    baseline = rows[0]["total_s"]
    for row in rows:
        row["speedup_vs_empty"] = round(baseline / row["total_s"], 2) if row["total_s"] else None
        row["hit_rate"] = round(row["hits"] / row["calls"], 4) if row["calls"] else None
    print(json.dumps({"rows": rows}))


if __name__ == "__main__":
    main()
