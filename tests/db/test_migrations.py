"""Migrations: an empty database upgraded to head matches the ORM metadata exactly."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory

from trajcache.db import cartesian, end_poses, migrate  # noqa: F401  (registers their tables)
from trajcache.db.base import Base
from trajcache.db.models import Trajectory

TABLES = {
    "api_keys",
    "cartesian_paths",
    "end_pose_backlog",
    "model_files",
    "plan_event_rollup_state",
    "plan_event_rollups",
    "plan_events",
    "robot_models",
    "robots",
    "scene_versions",
    "seed_job_scenes",
    "seed_jobs",
    "trajectories",
    "trajectory_certificates",
    "trajectory_commits",
    "trajectory_end_poses",
    "trajectory_tombstones",
}


def schema_diff(url: str) -> list[Any]:
    engine = sa.create_engine(url)
    try:
        with engine.connect() as conn:
            context = MigrationContext.configure(conn, opts={"compare_type": True})
            return list(compare_metadata(context, Base.metadata))
    finally:
        engine.dispose()


def table_names(url: str) -> set[str]:
    engine = sa.create_engine(url)
    try:
        return set(sa.inspect(engine).get_table_names())
    finally:
        engine.dispose()


def head_revision() -> str | None:
    return ScriptDirectory.from_config(migrate.alembic_config("sqlite://")).get_current_head()


def test_single_head() -> None:
    script = ScriptDirectory.from_config(migrate.alembic_config("sqlite://"))
    assert len(script.get_heads()) == 1


def test_upgrade_empty_database_matches_models(database_url: str) -> None:
    assert migrate.current_revision(database_url) is None
    migrate.upgrade(database_url)
    assert migrate.current_revision(database_url) == head_revision()
    assert table_names(database_url) == TABLES | {"alembic_version"}
    assert schema_diff(database_url) == []


def test_diff_detects_a_column_missing_from_migrations(database_url: str) -> None:
    migrate.upgrade(database_url)
    metadata = sa.MetaData(naming_convention=Base.metadata.naming_convention)
    for table in Base.metadata.sorted_tables:
        table.to_metadata(metadata)
    sa.Table(
        Trajectory.__tablename__,
        metadata,
        sa.Column("unmigrated", sa.Integer()),
        extend_existing=True,
    )
    engine = sa.create_engine(database_url)
    try:
        with engine.connect() as conn:
            context = MigrationContext.configure(conn, opts={"compare_type": True})
            diff = compare_metadata(context, metadata)
    finally:
        engine.dispose()
    assert [d[0] for d in diff] == ["add_column"]
    assert diff[0][3].name == "unmigrated"


def test_downgrade_to_base_and_upgrade_again(database_url: str) -> None:
    migrate.upgrade(database_url)
    migrate.downgrade(database_url, "base")
    assert migrate.current_revision(database_url) is None
    assert table_names(database_url) <= {"alembic_version"}
    migrate.upgrade(database_url)
    assert migrate.current_revision(database_url) == head_revision()
    assert schema_diff(database_url) == []


def _columns(engine: sa.Engine, table: str) -> set[str]:
    return {c["name"] for c in sa.inspect(engine).get_columns(table)}


def _before_requesters(engine: sa.Engine, callers: list[str]) -> None:
    """At revision 0007: seed job 3 and a plan event and a rollup row of each caller."""
    metadata = sa.MetaData()
    metadata.reflect(
        engine, only=["robot_models", "seed_jobs", "plan_events", "plan_event_rollups"]
    )
    t = metadata.tables
    now = datetime.now(UTC)
    timings = {"lookup_ms": 0.1, "validate_ms": 1.0, "plan_ms": 0.0, "total_ms": 1.5}
    with engine.begin() as conn:
        conn.execute(
            sa.insert(t["robot_models"]),
            {"id": "m", "name": "m", "base": "fixed", "joint_names": [], "urdf": "<robot/>",
             "allowed_pairs": [], "config": {}, "created_at": now},
        )  # fmt: skip
        conn.execute(
            sa.insert(t["seed_jobs"]),
            {"id": 3, "model_id": "m", "state": "completed", "spec": {}, "total": 1, "done": 1,
             "hits": 1, "planned": 0, "failed": 0, "errors": [], "created_at": now,
             "updated_at": now},
        )  # fmt: skip
        event = {"created_at": now, "model_id": "m", "status": "success", "source": "cache"}
        conn.execute(
            sa.insert(t["plan_events"]),
            [{**event, **timings, "robot_id": c, "candidates_tried": 1} for c in callers],
        )
        rollup = {"bucket_start": now, "model_id": "m", "status": "success", "source": "cache"}
        conn.execute(
            sa.insert(t["plan_event_rollups"]),
            [
                {**rollup, **timings, "robot_id": c, "requests": 2, "histograms": b""}
                for c in callers
            ],
        )


def test_existing_plan_events_get_their_requester(database_url: str) -> None:
    """Callers named after a seed job that exists were that job; every other caller a robot."""
    expected = {
        "robot-7": "robot",
        "seed-job-3": "seed_job",
        "seed-job-4": "robot",  # no such job: a robot of that name
        "seed-job-03": "robot",
        "seed-job-3x": "robot",
    }
    migrate.upgrade(database_url, "0007")
    engine = sa.create_engine(database_url)
    try:
        _before_requesters(engine, list(expected))
        migrate.upgrade(database_url)
        with engine.connect() as conn:
            for table in ("plan_events", "plan_event_rollups"):
                query = sa.text(f"SELECT robot_id, requester FROM {table}")
                assert dict(conn.execute(query).all()) == expected, table
        migrate.downgrade(database_url, "0007")
        for table in ("plan_events", "plan_event_rollups"):
            assert "requester" not in _columns(engine, table)
        assert "ix_plan_events_requester_created_at" not in {
            i["name"] for i in sa.inspect(engine).get_indexes("plan_events")
        }
    finally:
        engine.dispose()


def test_sqlite_ids_are_never_reused(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'autoinc.db'}"
    migrate.upgrade(url)
    engine = sa.create_engine(url)
    try:
        with engine.connect() as conn:
            sql: dict[str, str] = dict(
                conn.execute(sa.text("SELECT name, sql FROM sqlite_master")).all()
            )
    finally:
        engine.dispose()
    for table in ("trajectories", "trajectory_tombstones", "trajectory_commits", "plan_events"):
        assert "AUTOINCREMENT" in sql[table]


@pytest.mark.postgres
def test_postgres_version_table_lands_in_search_path_schema(postgres_url: str) -> None:
    migrate.upgrade(postgres_url)
    schema = postgres_url.rsplit("%3D", 1)[1]
    engine = sa.create_engine(postgres_url)
    try:
        with engine.connect() as conn:
            rows = conn.execute(
                sa.text(
                    "SELECT table_schema, table_name FROM information_schema.tables "
                    "WHERE table_name IN ('alembic_version', 'trajectories')"
                    " AND table_schema = :schema"
                ),
                {"schema": schema},
            ).all()
            version = conn.execute(
                sa.text(f'SELECT version_num FROM "{schema}".alembic_version')
            ).scalar_one()
    finally:
        engine.dispose()
    assert {name for _, name in rows} == {"alembic_version", "trajectories"}
    assert version == head_revision()


def test_trajectories_stored_before_the_end_pose_index_wait_in_its_backlog(
    database_url: str,
) -> None:
    migrate.upgrade(database_url, "0015")
    engine = sa.create_engine(database_url)
    try:
        metadata = sa.MetaData()
        metadata.reflect(engine, only=["robot_models", "trajectories"])
        t = metadata.tables
        now = datetime.now(UTC)
        with engine.begin() as conn:
            conn.execute(
                sa.insert(t["robot_models"]),
                {"id": "m", "name": "m", "base": "fixed", "joint_names": ["j"],
                 "urdf": "<robot/>", "allowed_pairs": [], "config": {}, "created_at": now},
            )  # fmt: skip
            states = {
                "states": b"", "n_states": 2, "dof": 1, "start": [0.0], "goal": [1.0],
                "start_x": 0.0, "start_y": 0.0, "goal_x": 1.0, "goal_y": 0.0, "env": {},
                "hits": 0, "failures": 0, "consecutive_failures": 0, "real_validations": 0,
                "created_at": now, "quality_pending": False,
            }  # fmt: skip
            conn.execute(
                sa.insert(t["trajectories"]),
                [{**states, "model_id": "m", "source": "sim", "content_hash": h} for h in "ab"],
            )
        migrate.upgrade(database_url)
        with engine.connect() as conn:
            backlog = conn.execute(sa.text("SELECT trajectory_id FROM end_pose_backlog")).all()
            kinds = conn.execute(sa.text("SELECT goal_kind FROM plan_events")).all()
        assert len(backlog) == 2 and kinds == []
        migrate.downgrade(database_url, "0015")
        assert "end_pose_backlog" not in sa.inspect(engine).get_table_names()
    finally:
        engine.dispose()
