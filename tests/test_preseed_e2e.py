"""Pre-seeding end to end: simulate → export → import elsewhere → a real robot starts warm.

1. A service on SQLite runs a seed job: the reference door sweep (doors at 0°, 10°, 80°, 90°;
   the first calls of each run) through the local worker pool, stored as `sim`.
2. `trajcache export` writes the cache (model included) to a gzipped JSON Lines file.
3. `trajcache import` loads it into a fresh PostgreSQL database.
4. A service on that database, with fallback planning off, serves a `real` robot running the
   perturbed cleaning run (fixtures shifted, door angles between the seeded ones, larger
   execution noise): its requests are answered from the imported cache.
5. The hits update the simulated trajectories' real-robot validation statistics.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient
from typer.testing import CliRunner

from tests.conftest import POSTGRES_URL, require_service
from tests.waiting import wait_until
from trajcache.cli import app as cli
from trajcache.core.config import Settings
from trajcache.db.models import Trajectory
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.main import create_app
from trajcache.reference.cleaning import cleaning_run
from trajcache.reference.robot import reference_urdf

pytestmark = [pytest.mark.postgres, pytest.mark.slow]

SEEDED_DOORS = [0, 10, 80, 90]
CALLS = 16  # of each seeded run, and of the real robot's run
REAL_SEED = 7


@dataclass
class Pipeline:
    """What the steps produced."""

    pg_url: str
    model_id: str
    seed_job: dict[str, Any]
    imported: dict[int, str] = field(default_factory=dict)  # trajectory id -> source
    hits_at_import: dict[int, int] = field(default_factory=dict)  # hits in simulation
    answers: list[dict[str, Any]] = field(default_factory=list)
    statuses: list[int] = field(default_factory=list)


@pytest.fixture(scope="module")
def pg_url() -> Iterator[str]:
    """A fresh PostgreSQL schema for the whole module."""
    require_service("PostgreSQL", "127.0.0.1", 5432)
    schema = f"e2e_{uuid.uuid4().hex[:12]}"
    admin = sa.create_engine(POSTGRES_URL, isolation_level="AUTOCOMMIT")
    with admin.connect() as conn:
        conn.execute(sa.text(f'CREATE SCHEMA "{schema}"'))
    try:
        yield f"{POSTGRES_URL}?options=-csearch_path%3D{schema}"
    finally:
        with admin.connect() as conn:
            conn.execute(sa.text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()


def seed_in_simulation(url: str) -> tuple[str, dict[str, Any]]:
    settings = Settings(database_url=url, worker_prestart=False, seed_heartbeat_s=0.2)
    with TestClient(create_app(settings)) as sim:
        model = sim.post("/v1/robot-models", json={"urdf": reference_urdf(), "base": "planar"})
        assert model.status_code == 201, model.text
        model_id = model.json()["model_id"]
        job = sim.post(
            "/v1/seed-jobs",
            json={
                "model_id": model_id,
                "name": "door sweep",
                "workload": {
                    "name": "door_sweep",
                    "seed": 1,
                    "doors_deg": SEEDED_DOORS,
                    "limit": CALLS,
                },
            },
        )
        assert job.status_code == 202, job.text
        job_id = job.json()["job_id"]
        seen: list[dict[str, Any]] = [{}]

        def finished() -> bool:
            seen[0] = sim.get(f"/v1/seed-jobs/{job_id}").json()
            return seen[0]["state"] not in ("queued", "running")

        assert wait_until(finished, timeout_s=600, interval_s=0.2), seen[0]
        return model_id, seen[0]


def run_real_robot(pipeline: Pipeline) -> None:
    settings = Settings(database_url=pipeline.pg_url, worker_backend="none")
    run = cleaning_run(REAL_SEED, perturbed=True)
    with TestClient(create_app(settings)) as fleet:
        robot = fleet.put("/v1/robots/real-1", json={"model_id": pipeline.model_id, "kind": "real"})
        assert robot.status_code == 201 and robot.json()["kind"] == "real"
        current = None
        for call in run.calls[:CALLS]:
            scene = run.scene_for(call)
            if scene.hash != current:
                put = fleet.put("/v1/robots/real-1/scene", json=scene_to_payload(scene))
                assert put.status_code == 200, put.text
                current = scene.hash
            answer = fleet.post(
                "/v1/robots/real-1/plan",
                json={"start": call.start.tolist(), "goal": call.goal.tolist()},
            )
            pipeline.statuses.append(answer.status_code)
            pipeline.answers.append(answer.json())


@pytest.fixture(scope="module")
def pipeline(pg_url: str, tmp_path_factory: pytest.TempPathFactory) -> Pipeline:
    work = tmp_path_factory.mktemp("preseed")
    sim_url = f"sqlite:///{work / 'sim.db'}"
    model_id, job = seed_in_simulation(sim_url)
    result = Pipeline(pg_url=pg_url, model_id=model_id, seed_job=job)

    export = work / "sim-cache.jsonl.gz"
    runner = CliRunner()
    exported = runner.invoke(cli, ["export", "-o", str(export), "--database-url", sim_url])
    assert exported.exit_code == 0, exported.output
    imported = runner.invoke(cli, ["import", str(export), "--database-url", pg_url])
    assert imported.exit_code == 0, imported.output

    engine = sa.create_engine(pg_url)
    try:
        with engine.connect() as conn:
            rows = conn.execute(sa.select(Trajectory.id, Trajectory.source, Trajectory.hits)).all()
    finally:
        engine.dispose()
    result.imported = {int(r.id): r.source for r in rows}
    result.hits_at_import = {int(r.id): r.hits for r in rows}
    run_real_robot(result)
    return result


def stored(pg: str, ids: set[int]) -> list[Any]:
    engine = sa.create_engine(pg)
    try:
        with engine.connect() as conn:
            return list(
                conn.execute(
                    sa.select(
                        Trajectory.id,
                        Trajectory.source,
                        Trajectory.hits,
                        Trajectory.real_validations,
                        Trajectory.last_real_validated_at,
                    ).where(Trajectory.id.in_(ids))
                ).all()
            )
    finally:
        engine.dispose()


def test_the_seed_job_filled_the_simulation_cache(pipeline: Pipeline) -> None:
    job = pipeline.seed_job
    assert job["state"] == "completed", job
    assert job["total"] == len(SEEDED_DOORS) * CALLS
    assert job["failed"] == 0, job["errors"]
    assert job["planned"] > 0 and job["hits"] > 0  # later runs reuse what earlier ones planned
    assert job["planned"] == len(pipeline.imported)
    assert set(pipeline.imported.values()) == {"sim"}


def test_a_real_robot_on_a_perturbed_scene_hits_the_imported_cache(pipeline: Pipeline) -> None:
    assert pipeline.statuses == [200] * CALLS
    hits = [a for a in pipeline.answers if a["status"] == "success"]
    # fallback planning is off on this service: every success is a validated cached trajectory
    assert all(a["source"] == "cache" for a in hits)
    assert all(a["trajectory_id"] in pipeline.imported for a in hits)
    assert len(hits) >= 0.75 * CALLS, [a["message"] for a in pipeline.answers]
    served = {a["trajectory_id"] for a in hits}
    rows = stored(pipeline.pg_url, served)
    assert sum(r.hits - pipeline.hits_at_import[r.id] for r in rows) == len(hits)
    assert {r.source for r in rows} == {"sim"}


def test_real_robot_hits_update_the_sim_validation_statistics(pipeline: Pipeline) -> None:
    hits = [a for a in pipeline.answers if a["status"] == "success"]
    counted: dict[int, int] = {}
    for answer in hits:
        counted[answer["trajectory_id"]] = counted.get(answer["trajectory_id"], 0) + 1
    rows = stored(pipeline.pg_url, set(counted))
    assert rows
    for row in rows:
        assert row.real_validations == counted[row.id]
        assert row.last_real_validated_at is not None
