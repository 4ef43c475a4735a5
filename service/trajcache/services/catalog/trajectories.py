"""Cached trajectories: store (deduplicated by content), list, read and delete with a tombstone."""

from __future__ import annotations

import dataclasses
import functools
import logging
from collections.abc import Mapping, Sized
from typing import Any, cast

import numpy as np
import numpy.typing as npt
import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, defer

from trajcache.core.config import Settings
from trajcache.db import models as tables
from trajcache.db.commit_log import log_commit
from trajcache.db.states import state_columns
from trajcache.geometry.errors import GeometryError, StateError
from trajcache.geometry.model.kinematics import check_limits, check_states
from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.scene.fields import parse_env
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import ValidatorCache
from trajcache.services.catalog.end_poses import write_end_poses
from trajcache.services.catalog.robots import check_robot_id
from trajcache.services.catalog.scene_cache import SceneCache
from trajcache.services.errors import (
    ConflictError,
    InvalidInputError,
    NotFoundError,
    PayloadTooLargeError,
)
from trajcache.services.quality import trajectory_quality

logger = logging.getLogger(__name__)

SOURCES = ("real", "sim", "import", "planner")
_COLUMNS = tuple(attr.key for attr in sa.inspect(tables.Trajectory).column_attrs)


@dataclasses.dataclass(frozen=True)
class NewTrajectory:
    """A trajectory to store: `model`'s states, where they come from and where they were planned.

    With `require_robot`, `robot_id` must name a robot of this model. `scene`, when given, is
    the parsed scene of `scene_hash` (it spares reading the stored version). At most
    `max_states` states, when set.
    """

    model: RobotModel
    states: npt.ArrayLike
    source: str
    robot_id: str | None = None
    scene_hash: str | None = None
    scene: Scene | None = None
    env: Mapping[str, Any] | None = None
    planning_time_ms: float | None = None
    max_states: int | None = None
    require_robot: bool = False


def store_trajectory(
    *,
    session: Session,
    settings: Settings,
    trajectory: NewTrajectory,
    commit: bool = True,
    compute_quality: bool = True,
    scenes: SceneCache | None = None,
    validators: ValidatorCache | None = None,
    commit_ids: list[int] | None = None,
) -> tuple[int, bool]:
    """Store `trajectory`; an identical one already stored is returned, not copied.

    States are checked for length, finiteness and joint limits (StateError names the joint);
    with `commit=False` the row is only flushed (the caller commits it with other writes).

    A new row gets its quality columns (`compute_quality`) under the caller's `settings` (the
    app's, never the process environment's): path lengths, duration after time-optimal timing
    and, in the trajectory's scene or else the stored scene version with its `scene_hash`, the
    minimum clearance. A metric that cannot be computed is left empty; the store proceeds.
    `scenes` and `validators` (the service's caches) spare parsing the scene and building its
    validator again. A new row's end poses (`end_poses`) and commit-log row go in its transaction;
    the log row's id is appended to `commit_ids` (the plan flow indexes its own row by it).
    """
    t, model = trajectory, trajectory.model
    array = _validated(
        session,
        model,
        t.states,
        source=t.source,
        robot_id=t.robot_id,
        scene_hash=t.scene_hash,
        max_states=t.max_states,
        require_robot=t.require_robot,
    )
    row = tables.Trajectory(model_id=model.model_id, source=t.source, robot_id=t.robot_id)
    row.scene_hash, row.env = t.scene_hash, parse_env(dict(t.env or {}))
    row.planning_time_ms = t.planning_time_ms
    row.set_states(array)
    if compute_quality:  # a stored copy needs no quality: look first (else the insert finds it)
        existing = _find(session, model.model_id, row.content_hash)
        if existing is not None:
            return existing, False
        scene = t.scene
        if scene is None and t.scene_hash is not None:
            scene = scene_with_hash(session, t.scene_hash, scenes)
        values = quality_columns(model, array, settings, scene, validators=validators)
        for name, value in (values or {}).items():  # empty where a metric cannot be computed
            setattr(row, name, value)
    new_id = _insert_unless_present(session, row)
    if new_id is None:  # stored before, or concurrently by another request or replica
        return _stored_already(session, row), False
    write_end_poses(session, model, [new_id], array[:1], array[-1:])
    logged = log_commit(session, new_id, new_id)  # replicas' syncs read the new row through it
    if commit_ids is not None:
        commit_ids.append(logged)
    if commit:
        session.commit()
    return new_id, True


def new_row_values(
    model: RobotModel,
    states: npt.ArrayLike,
    *,
    source: str,
    robot_id: str | None = None,
    scene_hash: str | None = None,
    env: Mapping[str, Any] | None = None,
    planning_time_ms: float | None = None,
    max_states: int | None = None,
) -> dict[str, Any]:
    """The column values of a new row of `model` (for a bulk INSERT), its states checked as
    `store_trajectory` checks them (the robot's existence is not: bulk writers store history
    of robots long gone)."""
    array = _checked_states(model, states)
    _check_count(array.shape[0], max_states)
    if source not in SOURCES:
        raise InvalidInputError(f"source {source!r} must be one of {', '.join(SOURCES)}")
    if robot_id is not None:
        check_robot_id(robot_id)
    if scene_hash is not None and not 1 <= len(scene_hash) <= 64:
        raise InvalidInputError("scene_hash must be 1-64 characters")
    return {
        "model_id": model.model_id,
        "source": source,
        "robot_id": robot_id,
        "scene_hash": scene_hash,
        "env": parse_env(dict(env or {})),
        "planning_time_ms": planning_time_ms,
        **state_columns(array),
    }


def _checked_states(model: RobotModel, states: npt.ArrayLike) -> np.ndarray:
    """`check_states` and `check_limits` in one pass for states that pass them (the bulk of an
    import): finite and within the limits without their tolerance. Anything else goes through
    the two checks, which accept what is within tolerance and name what is wrong."""
    try:
        array = np.asarray(states, dtype=np.float64)
    except (TypeError, ValueError):
        array = np.empty((0, 0))
    if array.ndim == 2 and array.shape[1] == model.dof and np.isfinite(array).all():
        lower, upper = _strict_limits(model)
        if ((array >= lower) & (array <= upper)).all():
            return array
    array = check_states(model, states, name="state")
    check_limits(model, array, name="state")
    return array


@functools.lru_cache(maxsize=64)
def _strict_limits(model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """The joint limits `check_limits` applies, without its tolerance (a planar base's x, y
    and theta unbounded)."""
    lower, upper = model.lower.astype(np.float64), model.upper.astype(np.float64)
    if model.base is BaseType.PLANAR:
        lower[:3], upper[:3] = -np.inf, np.inf
    return lower, upper


def set_parent(session: Session, trajectory_id: int, parent_id: int) -> None:
    """Name the trajectory a stored one was repaired from, unless it already names one (an
    identical path stored before keeps its own provenance); the caller commits."""
    _T = tables.Trajectory
    session.execute(
        sa.update(_T)
        .where(_T.id == trajectory_id, _T.parent_id.is_(None), _T.id != parent_id)
        .values(parent_id=parent_id)
    )


def _stored_already(session: Session, row: tables.Trajectory) -> int:
    """The id of the identical trajectory stored before (earlier, or by a concurrent writer)."""
    existing = _find(session, row.model_id, row.content_hash)
    if existing is None:
        raise ConflictError("trajectory was stored and deleted concurrently; retry")
    return existing


def _validated(
    session: Session,
    model: RobotModel,
    states: npt.ArrayLike,
    *,
    source: str,
    robot_id: str | None,
    scene_hash: str | None,
    max_states: int | None,
    require_robot: bool,
) -> np.ndarray:
    """The states as an array, checked with the source, robot and scene they are stored under."""
    if source not in SOURCES:
        raise InvalidInputError(f"source {source!r} must be one of {', '.join(SOURCES)}")
    _check_count(len(states) if isinstance(states, Sized) else None, max_states)
    array = check_states(model, states, name="state")
    _check_count(array.shape[0], max_states)
    check_limits(model, array, name="state")
    if robot_id is not None:
        check_robot_id(robot_id)
        if require_robot:
            _check_robot(session, robot_id, model.model_id)
    if scene_hash is not None and not 1 <= len(scene_hash) <= 64:
        raise InvalidInputError("scene_hash must be 1-64 characters")
    return array


def scene_with_hash(session: Session, scene_hash: str, scenes: SceneCache | None) -> Scene | None:
    """The scene with this hash, a robot's version or else a seed job's, parsed once per
    `scenes`; None if none is stored."""
    cached = scenes.get(scene_hash) if scenes is not None else None
    if cached is not None:
        return cached
    payload = None
    for table in (tables.SceneVersion, tables.SeedJobScene):
        query = sa.select(table.payload).where(table.hash == scene_hash).limit(1)
        if (payload := session.scalar(query)) is not None:
            break
    if payload is None:
        return None
    try:
        scene = parse_scene(payload)
    except GeometryError:  # stored before a parser change; clearance stays unknown
        logger.warning("stored scene %s no longer parses", scene_hash, exc_info=True)
        return None
    scene = dataclasses.replace(scene, hash=scene_hash)
    return scenes.put(scene) if scenes is not None else scene


def quality_columns(
    model: RobotModel,
    states: np.ndarray,
    settings: Settings,
    scene: Scene | None,
    *,
    validators: ValidatorCache | None = None,
) -> dict[str, Any] | None:
    """The quality columns of a trajectory (`trajectory_quality`): path lengths, clearance in
    `scene`, duration; None when they cannot be computed (a metric never blocks storing)."""
    try:
        quality, details = trajectory_quality(
            model, states, settings, scene=scene, validators=validators
        )
    except (ValueError, RuntimeError) as exc:
        logger.warning("quality of a new trajectory could not be computed: %s", exc)
        return None
    return {
        "length": quality.path_length,
        "ee_length": quality.ee_path_length,
        "min_clearance": quality.min_clearance,
        "duration_s": quality.duration_s,
        "quality": details,
    }


def _check_count(count: int | None, max_states: int | None) -> None:
    if count is None:
        return
    if count < 2:
        raise StateError(f"a trajectory needs at least 2 states, got {count}")
    if max_states is not None and count > max_states:
        raise PayloadTooLargeError(
            f"trajectory has {count} states, more than max_trajectory_states={max_states}"
        )


def _check_robot(session: Session, robot_id: str, model_id: str) -> None:
    robot_model = session.scalar(
        sa.select(tables.Robot.model_id).where(tables.Robot.id == robot_id)
    )
    if robot_model is None:
        raise NotFoundError(f"robot {robot_id!r} not found")
    if robot_model != model_id:
        raise ConflictError(
            f"robot {robot_id!r} is of model {robot_model!r}, not of model {model_id!r}"
        )


def _find(session: Session, model_id: str, content_hash: str) -> int | None:
    found = session.scalar(
        sa.select(tables.Trajectory.id).where(
            tables.Trajectory.model_id == model_id, tables.Trajectory.content_hash == content_hash
        )
    )
    return None if found is None else int(found)


def _insert_unless_present(session: Session, row: tables.Trajectory) -> int | None:
    """INSERT … ON CONFLICT (model_id, content_hash) DO NOTHING; the new id, or None. One Core
    statement per dialect, built once (building it from the values took 0.5 ms a time)."""
    values = {key: getattr(row, key) for key in _COLUMNS if key in row.__dict__}
    dialect = session.get_bind().dialect.name
    if dialect in ("postgresql", "sqlite"):
        new_id = session.execute(_insert_statement(dialect), values).scalar_one_or_none()
        return None if new_id is None else int(new_id)
    try:  # other databases: a savepoint around a plain insert
        with session.begin_nested():
            session.add(row)
        return int(row.id)
    except IntegrityError:
        return None


@functools.cache
def _insert_statement(dialect: str) -> sa.Insert:
    table = cast(sa.Table, tables.Trajectory.__table__)  # Core: not the ORM's bulk insert
    insert = postgresql.insert if dialect == "postgresql" else sqlite.insert
    return (
        insert(table)
        .on_conflict_do_nothing(index_elements=["model_id", "content_hash"])
        .returning(table.c.id)
    )


def list_trajectories(
    *,
    session: Session,
    model_id: str | None = None,
    source: str | None = None,
    robot_id: str | None = None,
    limit: int,
    offset: int = 0,
) -> tuple[list[tables.Trajectory], int]:
    """A page of trajectories (by id, without their states) and the total matching count."""
    conditions = []
    if model_id is not None:
        conditions.append(tables.Trajectory.model_id == model_id)
    if source is not None:
        conditions.append(tables.Trajectory.source == source)
    if robot_id is not None:
        conditions.append(tables.Trajectory.robot_id == robot_id)
    total = session.execute(
        sa.select(sa.func.count()).select_from(tables.Trajectory).where(*conditions)
    ).scalar_one()
    rows = session.scalars(
        sa.select(tables.Trajectory)
        .options(defer(tables.Trajectory.states, raiseload=True))
        .where(*conditions)
        .order_by(tables.Trajectory.id)
        .limit(limit)
        .offset(offset)
    ).all()
    return list(rows), int(total)


def get_trajectory(*, session: Session, trajectory_id: int) -> tables.Trajectory:
    """The trajectory `trajectory_id` with its states."""
    row = session.get(tables.Trajectory, trajectory_id)
    if row is None:
        raise NotFoundError(f"trajectory {trajectory_id} not found")
    return row


def trajectory_states(row: tables.Trajectory) -> list[list[float]]:
    """The key states of a stored trajectory as nested lists."""
    states: np.ndarray = row.states_array()
    return states.tolist()


def delete_trajectory(*, session: Session, trajectory_id: int) -> None:
    """Delete a trajectory and leave a tombstone (one transaction) so replicas drop it too."""
    model_id = session.execute(
        sa.delete(tables.Trajectory)
        .where(tables.Trajectory.id == trajectory_id)
        .returning(tables.Trajectory.model_id)
    ).scalar_one_or_none()
    if model_id is None:
        session.rollback()
        raise NotFoundError(f"trajectory {trajectory_id} not found")
    session.add(tables.TrajectoryTombstone(trajectory_id=trajectory_id, model_id=model_id))
    session.commit()
