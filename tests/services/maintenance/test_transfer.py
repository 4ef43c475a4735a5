"""Export to and import from JSON Lines: round trip, idempotence, checks, filters."""

from __future__ import annotations

import json
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
import trimesh
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from tests.robots import MESH_URDF, TWO_JOINT_URDF
from trajcache.core.config import Settings
from trajcache.db import migrate
from trajcache.db.models import ModelFile, RobotModel, Trajectory
from trajcache.services.catalog.models import (
    ModelRegistration,
    ModelRegistry,
    get_model,
    register_model,
)
from trajcache.services.catalog.trajectories import NewTrajectory, store_trajectory
from trajcache.services.context import ServiceContext
from trajcache.services.errors import ConflictError, InvalidInputError, NotFoundError
from trajcache.services.maintenance.importer import ImportFormatError, import_lines
from trajcache.services.maintenance.transfer import (
    FORMAT,
    ExportFilter,
    count_exported,
    dumps,
    export_records,
)

LONG_AGO = datetime(2025, 1, 2, 3, 4, 5, tzinfo=UTC)


def new_ctx(url: str) -> ServiceContext:
    migrate.upgrade(url)
    return ServiceContext.create(Settings(database_url=url, worker_backend="none"))


@pytest.fixture
def source_ctx(tmp_path: Path) -> Iterator[ServiceContext]:
    ctx = new_ctx(f"sqlite:///{tmp_path / 'source.db'}")
    yield ctx
    ctx.close()


@pytest.fixture
def target_ctx(database_url: str) -> Iterator[ServiceContext]:
    ctx = new_ctx(database_url)
    yield ctx
    ctx.close()


def fill(ctx: ServiceContext) -> dict[str, Any]:
    """Two models (one with a mesh file) and four trajectories with usage and provenance."""
    stl = bytes(trimesh.creation.box(extents=(0.1, 0.1, 0.2)).export(file_type="stl"))
    with ctx.sessions() as session:
        arm, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(urdf=TWO_JOINT_URDF),
        )
        lift, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(urdf=MESH_URDF, files={"meshes/part.stl": stl}),
        )
        session.execute(
            sa.update(RobotModel)
            .where(RobotModel.id == arm.model_id)
            .values(jerk_limits={"shoulder": 9.0, "elbow": 8.0})
        )
        ids = []
        for k, source in enumerate(("sim", "sim", "real")):
            new_id, _ = store_trajectory(
                session=session,
                settings=Settings(),
                trajectory=NewTrajectory(
                    model=arm,
                    states=[[0.0, 0.0], [0.1 * k, 0.2], [0.5, 0.5 + 0.1 * k]],
                    source=source,
                    robot_id="robot-1" if source == "real" else None,
                    scene_hash="ab" * 32,
                    env={"door": 0.1 * k},
                    planning_time_ms=12.5,
                ),
            )
            ids.append(new_id)
        lift_id, _ = store_trajectory(
            session=session,
            settings=Settings(),
            trajectory=NewTrajectory(model=lift, states=[[0.0], [0.4]], source="planner"),
        )
        session.execute(
            sa.update(Trajectory)
            .where(Trajectory.id == ids[0])
            .values(
                hits=7,
                failures=2,
                consecutive_failures=1,
                real_validations=3,
                created_at=LONG_AGO,
                last_used_at=LONG_AGO + timedelta(days=1),
                last_real_validated_at=LONG_AGO + timedelta(days=2),
            )
        )
        session.commit()
    return {"arm": arm.model_id, "lift": lift.model_id, "ids": ids, "lift_id": lift_id, "stl": stl}


def export_lines(ctx: ServiceContext, filt: ExportFilter | None = None, **kw: Any) -> list[str]:
    with ctx.sessions() as session:
        return [
            dumps(r) for r in export_records(session=session, filt=filt or ExportFilter(), **kw)
        ]


def run_import(ctx: ServiceContext, lines: list[str], **kw: Any) -> Any:
    with ctx.sessions() as session:
        return import_lines(
            session=session, registry=ModelRegistry(), settings=ctx.settings, lines=lines, **kw
        )


def rows(ctx: ServiceContext) -> list[Trajectory]:
    with ctx.sessions() as session:
        return list(session.scalars(sa.select(Trajectory).order_by(Trajectory.content_hash)))


def test_round_trip_keeps_models_provenance_and_usage(
    source_ctx: ServiceContext, target_ctx: ServiceContext
) -> None:
    filled = fill(source_ctx)
    lines = export_lines(source_ctx)
    records = [json.loads(line) for line in lines]
    assert records[0]["type"] == "header" and records[0]["format"] == FORMAT
    assert [r["type"] for r in records[1:]].count("model") == 2
    assert [r["type"] for r in records[1:]].count("trajectory") == 4

    report = run_import(target_ctx, lines)
    assert (report.inserted, report.duplicates, report.rejected_count) == (4, 0, 0)
    assert (report.models_created, report.models_existing) == (2, 0)

    before, after = rows(source_ctx), rows(target_ctx)
    fields = [
        "model_id",
        "source",
        "robot_id",
        "scene_hash",
        "env",
        "content_hash",
        "planning_time_ms",
        "hits",
        "failures",
        "consecutive_failures",
        "real_validations",
        "created_at",
        "last_used_at",
        "last_validated_at",
        "last_real_validated_at",
        "n_states",
        "dof",
        "start",
        "goal",
    ]
    for old, new in zip(before, after, strict=True):
        for name in fields:
            assert getattr(new, name) == getattr(old, name), name
        assert new.states == old.states
    with target_ctx.sessions() as session:
        arm = session.get(RobotModel, filled["arm"])
        assert arm is not None and arm.jerk_limits == {"shoulder": 9.0, "elbow": 8.0}
        files = session.scalars(
            sa.select(ModelFile).where(ModelFile.model_id == filled["lift"])
        ).all()
        assert [(f.path, f.data) for f in files] == [("meshes/part.stl", filled["stl"])]
        assert (
            get_model(session=session, registry=ModelRegistry(), model_id=filled["lift"]).dof == 1
        )


def test_import_is_idempotent(source_ctx: ServiceContext, target_ctx: ServiceContext) -> None:
    fill(source_ctx)
    lines = export_lines(source_ctx)
    run_import(target_ctx, lines)
    again = run_import(target_ctx, lines)
    assert (again.inserted, again.duplicates, again.rejected_count) == (0, 4, 0)
    assert (again.models_created, again.models_existing) == (0, 2)
    assert len(rows(target_ctx)) == 4
    doubled = run_import(target_ctx, [lines[-2], lines[-2]])  # the last trajectory
    assert (doubled.inserted, doubled.duplicates) == (0, 2)


def test_bad_lines_are_rejected_with_reasons_and_the_rest_imported(
    source_ctx: ServiceContext, target_ctx: ServiceContext
) -> None:
    filled = fill(source_ctx)
    lines = export_lines(source_ctx, ExportFilter(model_ids=(filled["arm"],)))
    good = json.loads(lines[-2])  # the last trajectory

    def variant(**changes: Any) -> str:
        return dumps({**good, **changes})

    bad = [
        variant(states=[[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]]),
        variant(states=[[0.0, 0.0], [0.5, 2.5]]),
        variant(states=[[0.0, 0.0]]),
        variant(content_hash="0" * 64),
        variant(model_id="f" * 64),
        variant(hits=-1),
        variant(created_at="yesterday"),
        variant(source="dream"),
        variant(env={"door": "open"}),
        '{"type": "trajectory", "model_id": "x", "states": [[0, NaN]]}',
        '{"type": "nonsense"}',
        "[1, 2]",
    ]
    report = run_import(target_ctx, lines[:2] + bad + lines[2:])
    reasons = {r.line: r.reason for r in report.rejected}
    assert report.rejected_count == len(bad) == len(reasons)
    expected = [
        "has 3 values, expected 2",
        "out of joint limits: elbow",
        "at least 2 states",
        "content_hash does not match",
        "not in this database and the file has no model line",
        "hits must be a non-negative integer",
        "created_at 'yesterday' is not an ISO-8601",
        "source 'dream'",
        "env['door'] must be a number",
        "NaN is not a valid number",
        "unknown line type 'nonsense'",
        "a line must be a JSON object",
    ]
    for line_no, needle in zip(range(3, 3 + len(bad)), expected, strict=True):
        assert needle in reasons[line_no], (line_no, reasons[line_no])
    assert report.inserted == 3 and len(rows(target_ctx)) == 3


def test_a_line_that_is_not_json_imports_nothing(
    source_ctx: ServiceContext, target_ctx: ServiceContext
) -> None:
    fill(source_ctx)
    lines = export_lines(source_ctx)
    assert [json.loads(line)["type"] for line in lines[:2]] == ["header", "model"]
    cut = [*lines[:-1], lines[-2][:40]]  # a trajectory line cut short
    with pytest.raises(ImportFormatError, match=f"line {len(cut)}: not JSON"):
        run_import(target_ctx, cut)
    assert rows(target_ctx) == []
    with target_ctx.sessions() as session:  # the model line's registration was rolled back too
        assert session.scalar(sa.select(sa.func.count()).select_from(RobotModel)) == 0
    with target_ctx.sessions() as session, pytest.raises(NotFoundError):
        model_id = json.loads(lines[1])["model_id"]
        get_model(session=session, registry=target_ctx.models, model_id=model_id)


def test_without_model_lines_the_models_must_exist(
    source_ctx: ServiceContext, target_ctx: ServiceContext
) -> None:
    filled = fill(source_ctx)
    lines = export_lines(source_ctx, include_models=False)
    assert all(json.loads(line)["type"] != "model" for line in lines)
    report = run_import(target_ctx, lines)
    assert (report.inserted, report.rejected_count) == (0, 4)
    with target_ctx.sessions() as session:
        register_model(
            session=session,
            registry=ModelRegistry(),
            registration=ModelRegistration(urdf=TWO_JOINT_URDF),
        )
    report = run_import(target_ctx, lines)
    assert (report.inserted, report.rejected_count) == (3, 1)
    assert filled["lift"][:8] in report.rejected[0].reason


def test_source_override(source_ctx: ServiceContext, target_ctx: ServiceContext) -> None:
    fill(source_ctx)
    run_import(target_ctx, export_lines(source_ctx), source="import")
    assert {t.source for t in rows(target_ctx)} == {"import"}
    with target_ctx.sessions() as session, pytest.raises(InvalidInputError, match="source"):
        import_lines(
            session=session,
            registry=ModelRegistry(),
            settings=target_ctx.settings,
            lines=[],
            source="x",
        )


def test_foreign_or_newer_files_are_refused(target_ctx: ServiceContext) -> None:
    with pytest.raises(ImportFormatError, match="not a trajcache export"):
        run_import(target_ctx, [dumps({"type": "header", "format": "other", "version": 1})])
    with pytest.raises(ImportFormatError, match="version 9 is newer"):
        run_import(target_ctx, [dumps({"type": "header", "format": FORMAT, "version": 9})])


def test_export_filters(source_ctx: ServiceContext) -> None:
    filled = fill(source_ctx)

    def exported(**fields: Any) -> list[dict[str, Any]]:
        lines = export_lines(source_ctx, ExportFilter(**fields))
        return [r for r in map(json.loads, lines) if r["type"] == "trajectory"]

    assert len(exported()) == 4
    assert {r["model_id"] for r in exported(model_ids=(filled["lift"],))} == {filled["lift"]}
    assert {r["source"] for r in exported(sources=("sim",))} == {"sim"}
    assert len(exported(sources=("sim", "real"))) == 3
    old = exported(created_before=LONG_AGO + timedelta(days=1))
    assert [r["hits"] for r in old] == [7]
    assert len(exported(created_after=LONG_AGO + timedelta(days=1))) == 3
    with source_ctx.sessions() as session:
        assert count_exported(session, ExportFilter(sources=("sim",))) == 2
        with pytest.raises(NotFoundError):
            list(export_records(session=session, filt=ExportFilter(model_ids=("nope",))))
        with pytest.raises(InvalidInputError, match="source"):
            list(export_records(session=session, filt=ExportFilter(sources=("dream",))))


SRDF = """<robot name="two_joint">
  <group name="arm"><joint name="shoulder"/></group>
  <disable_collisions link1="base" link2="fore" reason="Never"/>
</robot>"""


def test_a_model_with_an_srdf_and_held_joints_keeps_its_id(
    source_ctx: ServiceContext, target_ctx: ServiceContext
) -> None:
    with source_ctx.sessions() as session:
        model, _ = register_model(
            session=session,
            registry=ModelRegistry(),
            registration=ModelRegistration(
                urdf=TWO_JOINT_URDF, srdf=SRDF, group="arm", joint_values={"elbow": 0.5}
            ),
        )
        store_trajectory(
            session=session,
            settings=Settings(),
            trajectory=NewTrajectory(model=model, states=[[0.0], [0.4]], source="sim"),
        )
    lines = export_lines(source_ctx)
    (record,) = [json.loads(line) for line in lines if json.loads(line)["type"] == "model"]
    assert (record["srdf"], record["joint_values"]) == (SRDF, {"elbow": 0.5})
    run_import(target_ctx, lines)
    with target_ctx.sessions() as session:
        imported = get_model(session=session, registry=ModelRegistry(), model_id=model.model_id)
    assert imported.held_values == {"elbow": 0.5}
    assert "srdf" in imported.pair_reasons.values()


def test_a_concurrent_writer_is_a_conflict_and_nothing_is_imported(
    source_ctx: ServiceContext, target_ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A uniqueness error at commit (another replica stored the same model meanwhile) rolls the
    whole import back and says to retry (409), instead of escaping as a server error."""
    fill(source_ctx)
    lines = export_lines(source_ctx)

    def racing_commit(self: Session) -> None:
        raise IntegrityError("INSERT INTO robot_models", {}, Exception("duplicate key"))

    monkeypatch.setattr(Session, "commit", racing_commit)
    with pytest.raises(ConflictError, match="stored concurrently"):
        run_import(target_ctx, lines)
    monkeypatch.undo()
    assert rows(target_ctx) == []
    with target_ctx.sessions() as session:
        assert session.scalar(sa.select(sa.func.count()).select_from(RobotModel)) == 0
