"""ORM tables on SQLite and PostgreSQL: inserts, state round-trips, constraints, cascades."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, sessionmaker

from tests.robots import OPAQUE_URDF
from trajcache.db.models import (
    ApiKey,
    ModelFile,
    PlanEvent,
    Robot,
    RobotModel,
    SceneVersion,
    Trajectory,
    TrajectoryTombstone,
    pack_states,
    trajectory_content_hash,
    unpack_states,
)
from trajcache.db.session import make_engine, make_sessionmaker


@pytest.fixture
def session_factory(migrated_url: str) -> Iterator[sessionmaker[Session]]:
    engine = make_engine(migrated_url, pool_size=2)
    try:
        yield make_sessionmaker(engine)
    finally:
        engine.dispose()


def awkward_states(n: int = 7, dof: int = 9) -> np.ndarray:
    rng = np.random.default_rng(7)
    states = rng.normal(scale=3.0, size=(n, dof))
    states[1, 2] = np.nextafter(0.0, 1.0)  # subnormal
    states[2, 3] = -0.0
    states[3, 4] = np.finfo(np.float64).max
    states[4, 5] = 1.0 / 3.0
    return states


def add_model(session: Session, model_id: str = "m" * 64) -> RobotModel:
    model = RobotModel(
        id=model_id,
        name="mobile-arm",
        base="planar",
        joint_names=["j1", "j2"],
        urdf=OPAQUE_URDF,
        allowed_pairs=[[0, 2], [1, 3]],
        config={"acceleration_limits": [1.0, 2.0]},
    )
    session.add(model)
    session.flush()
    return model


def make_trajectory(model_id: str, states: np.ndarray, **kwargs: object) -> Trajectory:
    trajectory = Trajectory(model_id=model_id, source="sim", env={"door": 0.5}, **kwargs)
    trajectory.set_states(states)
    return trajectory


def test_pack_unpack_is_bit_exact() -> None:
    states = awkward_states()
    data = pack_states(states)
    assert len(data) == states.size * 8
    assert data == states.astype("<f8").tobytes()
    back = unpack_states(data, n_states=7, dof=9)
    assert back.tobytes() == states.tobytes()
    back[0, 0] = 1.0  # writable copy
    with pytest.raises(ValueError):
        unpack_states(data, n_states=7, dof=8)
    with pytest.raises(ValueError):
        pack_states(np.zeros(3))


def test_insert_every_table(session_factory: sessionmaker[Session]) -> None:
    states = awkward_states()
    with session_factory() as session:
        model = add_model(session)
        model.files.append(ModelFile(path="meshes/base.stl", sha256="f" * 64, data=b"\x00\x01"))
        session.add(Robot(id="robot-1", model_id=model.id, scene_version=1))
        session.flush()
        session.add(
            SceneVersion(
                robot_id="robot-1", version=1, hash="h" * 64, payload={"objects": []}, env={}
            )
        )
        trajectory = make_trajectory(model.id, states, robot_id="robot-1", scene_hash="h" * 64)
        session.add(trajectory)
        session.flush()
        session.add(TrajectoryTombstone(trajectory_id=trajectory.id, model_id=model.id))
        session.add(
            PlanEvent(
                robot_id="robot-1",
                model_id=model.id,
                status="success",
                source="cache",
                trajectory_id=trajectory.id,
                candidates_tried=2,
                lookup_ms=0.5,
                validate_ms=3.25,
                total_ms=4.0,
            )
        )
        session.add(ApiKey(name="ops", prefix="tc_abc", key_hash="x" * 64, role="admin"))
        session.commit()
        trajectory_id = trajectory.id

    with session_factory() as session:
        stored = session.get_one(Trajectory, trajectory_id)
        assert stored.states_array().tobytes() == states.tobytes()
        assert (stored.n_states, stored.dof) == states.shape
        assert stored.start == states[0].tolist() and stored.goal == states[-1].tolist()
        assert (stored.start_x, stored.start_y) == (states[0, 0], states[0, 1])
        assert (stored.goal_x, stored.goal_y) == (states[-1, 0], states[-1, 1])
        assert stored.content_hash == trajectory_content_hash(states)
        assert (stored.hits, stored.failures, stored.consecutive_failures) == (0, 0, 0)
        assert stored.env == {"door": 0.5}
        assert stored.created_at.tzinfo is not None
        assert abs(datetime.now(UTC) - stored.created_at) < timedelta(minutes=1)

        model = session.get_one(RobotModel, "m" * 64)
        assert model.allowed_pairs == [[0, 2], [1, 3]]
        assert [f.path for f in model.files] == ["meshes/base.stl"]
        tombstone = session.scalars(sa.select(TrajectoryTombstone)).one()
        assert tombstone.trajectory_id == trajectory_id
        event = session.scalars(sa.select(PlanEvent)).one()
        assert (event.status, event.plan_ms, event.error) == ("success", 0.0, None)
        assert session.scalars(sa.select(ApiKey)).one().robot_ids == []
        assert session.get_one(Robot, "robot-1").scene_versions[0].hash == "h" * 64


def test_duplicate_content_hash_is_rejected(session_factory: sessionmaker[Session]) -> None:
    states = awkward_states()
    with session_factory() as session:
        model = add_model(session)
        other = add_model(session, "o" * 64)
        session.add(make_trajectory(model.id, states))
        session.add(make_trajectory(other.id, states))  # same content, other model: fine
        session.commit()

        session.add(make_trajectory(model.id, states.copy()))
        with pytest.raises(IntegrityError):
            session.commit()
        session.rollback()
        assert session.scalar(sa.select(sa.func.count()).select_from(Trajectory)) == 2


def test_robot_delete_cascades_to_scene_versions(
    session_factory: sessionmaker[Session],
) -> None:
    with session_factory() as session:
        model = add_model(session)
        session.add(Robot(id="r1", model_id=model.id))
        session.add(Robot(id="r2", model_id=model.id))
        session.flush()
        for robot_id in ("r1", "r2"):
            for version in (1, 2):
                session.add(
                    SceneVersion(robot_id=robot_id, version=version, hash=f"{version}", payload={})
                )
        session.commit()

    with session_factory() as session:
        # Core DELETE: the database's ON DELETE CASCADE does the work, not the ORM.
        session.execute(sa.delete(Robot).where(Robot.id == "r1"))
        session.commit()
        rows = session.execute(sa.select(SceneVersion.robot_id, SceneVersion.version)).all()
        assert sorted(rows) == [("r2", 1), ("r2", 2)]


def test_duplicate_scene_version_is_rejected(session_factory: sessionmaker[Session]) -> None:
    with session_factory() as session:
        model = add_model(session)
        session.add(Robot(id="r1", model_id=model.id))
        session.flush()
        session.add(SceneVersion(robot_id="r1", version=1, hash="a", payload={}))
        session.commit()
        session.add(SceneVersion(robot_id="r1", version=1, hash="b", payload={}))
        with pytest.raises(IntegrityError):
            session.commit()


def test_ids_are_not_reused_after_delete(session_factory: sessionmaker[Session]) -> None:
    with session_factory() as session:
        model = add_model(session)
        first = make_trajectory(model.id, awkward_states())
        session.add(first)
        session.commit()
        first_id = first.id
        session.delete(first)
        session.commit()
        second = make_trajectory(model.id, awkward_states() + 1.0)
        session.add(second)
        session.commit()
        assert second.id > first_id


def test_set_states_rejects_bad_shapes() -> None:
    with pytest.raises(ValueError):
        Trajectory().set_states(np.zeros((1, 3)))
    with pytest.raises(ValueError):
        Trajectory().set_states(np.zeros(5))


def test_sqlite_engine_pragmas(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'pragmas.db'}")
    try:
        with engine.connect() as conn:
            pragma = {
                name: conn.exec_driver_sql(f"PRAGMA {name}").scalar()
                for name in ("journal_mode", "foreign_keys", "busy_timeout", "synchronous")
            }
    finally:
        engine.dispose()
    assert pragma == {
        "journal_mode": "wal",
        "foreign_keys": 1,
        "busy_timeout": 5000,
        "synchronous": 1,
    }


def test_timestamps_are_utc_aware(session_factory: sessionmaker[Session]) -> None:
    local = datetime(2025, 1, 2, 12, 0, tzinfo=timezone(timedelta(hours=2)))
    with session_factory() as session:
        session.add(ApiKey(name="k", prefix="p", key_hash="h", role="robot", revoked_at=local))
        session.commit()
    with session_factory() as session:
        revoked = session.scalars(sa.select(ApiKey.revoked_at)).one()
        assert revoked == local and revoked.utcoffset() is not None
        later = session.scalar(
            sa.select(sa.func.count()).where(
                ApiKey.revoked_at > datetime(2025, 1, 2, 10, 30, tzinfo=UTC)
            )
        )
        assert later == 0  # 12:00+02:00 is 10:00 UTC
