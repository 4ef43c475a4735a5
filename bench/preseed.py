"""Pre-seeding through the API: the door sweep as seed jobs, then a "real robot" on a new scene.

The service is the real app (lifespan, migrations, background seed scheduler) on a fresh SQLite
file with the local planner pool (`--workers` processes), driven in-process over ASGI.

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
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from fastapi.testclient import TestClient

from trajcache.core.config import Settings
from trajcache.db.models import PlanEvent, Trajectory
from trajcache.geometry.reference.robot import reference_urdf
from trajcache.geometry.scene.scene import scene_to_payload
from trajcache.main import create_app
from trajcache.services.context import ServiceContext
from trajcache.workload.cleaning import cleaning_run

HEADER = (
    f"{'row':<28}{'calls':>6}{'hits':>6}{'plan':>6}{'fail':>6}{'cache':>7}"
    f"{'look+val s':>11}{'plan s':>8}{'total s':>9}{'wall s':>8}{'hit %':>7}"
)


def _ctx(client: TestClient) -> ServiceContext:
    ctx: ServiceContext = client.app.state.ctx  # type: ignore[attr-defined]
    return ctx


def _cache_size(client: TestClient) -> int:
    with _ctx(client).session() as session:
        return int(session.scalar(sa.select(sa.func.count()).select_from(Trajectory)) or 0)


def _event_sums(client: TestClient, robot_id: str) -> dict[str, float]:
    ctx = _ctx(client)
    ctx.records.flush()
    with ctx.session() as session:
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


def seed_row(client: TestClient, model_id: str, door: float, seed: int, limit: int | None) -> dict:
    """One seed job: the door-sweep run at `door` degrees."""
    workload: dict[str, Any] = {"name": "door_sweep", "seed": seed, "doors_deg": [door]}
    if limit is not None:
        workload["limit"] = limit
    began = time.perf_counter()
    job = client.post("/v1/seed-jobs", json={"model_id": model_id, "workload": workload})
    job.raise_for_status()
    job_id = job.json()["job_id"]
    while True:
        state = client.get(f"/v1/seed-jobs/{job_id}").json()
        if state["state"] not in ("queued", "running"):
            break
        time.sleep(0.2)
    wall = time.perf_counter() - began
    return {
        "row": f"seed job {job_id}: doors {door:g}°",
        "calls": state["total"],
        "hits": state["hits"],
        "planned": state["planned"],
        "failed": state["failed"],
        "cache": _cache_size(client),
        "wall_s": wall,
        **_event_sums(client, f"seed-job-{job_id}"),
    }


def real_row(client: TestClient, model_id: str, robot: str, seed: int, limit: int | None) -> dict:
    """The perturbed cleaning run by a `real` robot, every call through the plan endpoint."""
    put = client.put(f"/v1/robots/{robot}", json={"model_id": model_id, "kind": "real"})
    put.raise_for_status()
    run = cleaning_run(seed, perturbed=True)
    calls = run.calls[:limit]
    counts = {"hits": 0, "planned": 0, "failed": 0}
    current = None
    began = time.perf_counter()
    for call in calls:
        scene = run.scene_for(call)
        if scene.hash != current:
            client.put(f"/v1/robots/{robot}/scene", json=scene_to_payload(scene)).raise_for_status()
            current = scene.hash
        body = {"start": call.start.tolist(), "goal": call.goal.tolist()}
        answer = client.post(f"/v1/robots/{robot}/plan", json=body).json()
        if answer.get("status") != "success":
            counts["failed"] += 1
        else:
            counts["hits" if answer["source"] == "cache" else "planned"] += 1
    wall = time.perf_counter() - began
    return {
        "row": robot,
        "calls": len(calls),
        **counts,
        "cache": _cache_size(client),
        "wall_s": wall,
        **_event_sums(client, robot),
    }


def _app(url: str, workers: int) -> TestClient:
    settings = Settings(database_url=url, worker_processes=workers, seed_heartbeat_s=0.5)
    return TestClient(create_app(settings))


def _warm(client: TestClient) -> None:
    """Wait until the planner workers are up (a cold start would time out the first plans)."""
    pool = _ctx(client).planner_pool()
    wait_ready = getattr(getattr(pool, "backend", None), "wait_ready", None)
    if callable(wait_ready):
        wait_ready(300.0)


def _register(client: TestClient) -> str:
    model = client.post("/v1/robot-models", json={"urdf": reference_urdf(), "base": "planar"})
    model.raise_for_status()
    return str(model.json()["model_id"])


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
