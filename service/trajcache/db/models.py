"""ORM tables of the trajectory cache (schema changes go through `db/migrations/`)."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

import numpy as np
import numpy.typing as npt
from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    DateTime,
    Dialect,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import Mapped, mapped_column, relationship
from sqlalchemy.types import TypeDecorator

from trajcache.db.base import Base
from trajcache.db.states import STATE_DTYPE as STATE_DTYPE
from trajcache.db.states import pack_states as pack_states
from trajcache.db.states import state_columns, unpack_states
from trajcache.db.states import trajectory_content_hash as trajectory_content_hash

# SQLite only autoincrements INTEGER PRIMARY KEY; PostgreSQL gets a BIGINT identity.
BigIntPK = BigInteger().with_variant(Integer, "sqlite")


def utcnow() -> datetime:
    """The current time, timezone-aware in UTC."""
    return datetime.now(UTC)


class UTCDateTime(TypeDecorator[datetime]):
    """A timezone-aware timestamp; naive values read back (SQLite) are taken as UTC."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is not None and value.tzinfo is None:
            value = value.replace(tzinfo=UTC)
        if value is not None and dialect.name == "sqlite":
            value = value.astimezone(UTC)  # SQLite compares timestamps as text
        return value

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is not None and value.tzinfo is None:
            value = value.replace(tzinfo=UTC)
        return value


class RobotModel(Base):
    """A registered robot model, identified by the hash of its content."""

    __tablename__ = "robot_models"

    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    base: Mapped[str] = mapped_column(String(16))
    joint_names: Mapped[list[str]] = mapped_column(JSON)
    urdf: Mapped[str] = mapped_column(Text)
    allowed_pairs: Mapped[list[list[int]]] = mapped_column(JSON, default=list)
    config: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    # Limits by planning joint name (rad/s², rad/s³; m for prismatic joints) as registered;
    # joints not named, or None, use the service defaults.
    acceleration_limits: Mapped[dict[str, float] | None] = mapped_column(JSON)
    jerk_limits: Mapped[dict[str, float] | None] = mapped_column(JSON)
    # Link whose origin traces the end-effector path; None = tip of the longest joint chain.
    end_effector_link: Mapped[str | None] = mapped_column(String(200))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)

    files: Mapped[list[ModelFile]] = relationship(
        back_populates="model", cascade="all, delete-orphan", passive_deletes=True
    )


class ModelFile(Base):
    """A mesh (or other) file from a model's archive, addressed by its path inside it."""

    __tablename__ = "model_files"
    __table_args__ = (UniqueConstraint("model_id", "path"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    model_id: Mapped[str] = mapped_column(
        String(64), ForeignKey("robot_models.id", ondelete="CASCADE"), index=True
    )
    path: Mapped[str] = mapped_column(String(1024))
    sha256: Mapped[str] = mapped_column(String(64))
    data: Mapped[bytes] = mapped_column(LargeBinary)

    model: Mapped[RobotModel] = relationship(back_populates="files")


class Robot(Base):
    """A robot instance: its model and the number of its current scene version."""

    __tablename__ = "robots"

    id: Mapped[str] = mapped_column(String(128), primary_key=True)
    model_id: Mapped[str] = mapped_column(String(64), ForeignKey("robot_models.id"), index=True)
    scene_version: Mapped[int | None] = mapped_column(Integer)
    # `real`: a physical robot; `sim`: a simulated one (validation statistics tell them apart).
    kind: Mapped[str] = mapped_column(String(8), default="real", server_default="real")
    # Values of joints outside the planning joints that this robot holds otherwise than its
    # model does (e.g. the gripper open), as canonical JSON text; None: the model's.
    joint_values: Mapped[str | None] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, onupdate=utcnow)

    model: Mapped[RobotModel] = relationship()
    scene_versions: Mapped[list[SceneVersion]] = relationship(
        back_populates="robot", cascade="all, delete-orphan", passive_deletes=True
    )


class SceneVersion(Base):
    """One immutable version of a robot's scene (canonical native form) and its hash."""

    __tablename__ = "scene_versions"
    __table_args__ = (UniqueConstraint("robot_id", "version"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    robot_id: Mapped[str] = mapped_column(String(128), ForeignKey("robots.id", ondelete="CASCADE"))
    version: Mapped[int] = mapped_column(Integer)
    hash: Mapped[str] = mapped_column(String(64), index=True)
    payload: Mapped[dict[str, Any]] = mapped_column(JSON)
    env: Mapped[dict[str, float]] = mapped_column(JSON, default=dict)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)

    robot: Mapped[Robot] = relationship(back_populates="scene_versions")


class Trajectory(Base):
    """A cached trajectory: key states joined by straight lines in state space."""

    __tablename__ = "trajectories"
    __table_args__ = (
        UniqueConstraint("model_id", "content_hash"),
        Index("ix_trajectories_model_id_id", "model_id", "id"),
        Index("ix_trajectories_model_id_start_xy", "model_id", "start_x", "start_y"),
        # AUTOINCREMENT: ids never reused, so replicas can sync by high-water mark.
        {"sqlite_autoincrement": True},
    )

    id: Mapped[int] = mapped_column(BigIntPK, primary_key=True, autoincrement=True)
    model_id: Mapped[str] = mapped_column(String(64), ForeignKey("robot_models.id"))
    source: Mapped[str] = mapped_column(String(16))
    robot_id: Mapped[str | None] = mapped_column(String(128))
    states: Mapped[bytes] = mapped_column(LargeBinary)
    n_states: Mapped[int] = mapped_column(Integer)
    dof: Mapped[int] = mapped_column(Integer)
    start: Mapped[list[float]] = mapped_column(JSON)
    goal: Mapped[list[float]] = mapped_column(JSON)
    start_x: Mapped[float] = mapped_column(Float)
    start_y: Mapped[float] = mapped_column(Float)
    goal_x: Mapped[float] = mapped_column(Float)
    goal_y: Mapped[float] = mapped_column(Float)
    scene_hash: Mapped[str | None] = mapped_column(String(64))
    env: Mapped[dict[str, float]] = mapped_column(JSON, default=dict)
    content_hash: Mapped[str] = mapped_column(String(64))
    hits: Mapped[int] = mapped_column(Integer, default=0)
    failures: Mapped[int] = mapped_column(Integer, default=0)
    consecutive_failures: Mapped[int] = mapped_column(Integer, default=0)
    real_validations: Mapped[int] = mapped_column(Integer, default=0)
    last_used_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    last_validated_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    last_real_validated_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    planning_time_ms: Mapped[float | None] = mapped_column(Float)
    parent_id: Mapped[int | None] = mapped_column(BigInteger)  # a repair's source trajectory
    # Quality: path lengths, clearance to the recorded scene (m), time-optimal duration (s);
    # pending: an imported row's, computed in the background (`maintenance/backfill.py`).
    length: Mapped[float | None] = mapped_column(Float)
    ee_length: Mapped[float | None] = mapped_column(Float)
    min_clearance: Mapped[float | None] = mapped_column(Float)
    duration_s: Mapped[float | None] = mapped_column(Float)
    quality: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    quality_pending: Mapped[bool] = mapped_column(Boolean, default=False, index=True)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)

    def states_array(self) -> npt.NDArray[np.float64]:
        """The key states as a writable (n_states, dof) float64 array."""
        return unpack_states(self.states, n_states=self.n_states, dof=self.dof)

    def set_states(self, states: npt.ArrayLike) -> None:
        """Store key states and the columns derived from them (`state_columns`)."""
        for key, value in state_columns(states).items():
            setattr(self, key, value)


class TrajectoryCertificate(Base):
    """What validation proved about a trajectory's interior (`validation/certificates.py`);
    written by the service's validator only, never exported, deleted with its trajectory."""

    __tablename__ = "trajectory_certificates"
    __table_args__ = (UniqueConstraint("trajectory_id", "variant", "stamp", "path"),)

    id: Mapped[int] = mapped_column(BigIntPK, primary_key=True, autoincrement=True)
    trajectory_id: Mapped[int] = mapped_column(
        BigInteger, ForeignKey("trajectories.id", ondelete="CASCADE")
    )
    variant: Mapped[str] = mapped_column(String(64))  # the checked model's id
    stamp: Mapped[str] = mapped_column(String(64))  # of the certifier and validator settings
    path: Mapped[str] = mapped_column(String(64))  # digest of the interior states
    objects: Mapped[list[str]] = mapped_column(JSON)  # digests of the objects it was proved for
    # by object id: [digest of its shape and allowed names, its pose (12 floats), clearance]
    clearances: Mapped[dict[str, list[Any]] | None] = mapped_column(JSON, nullable=True)
    # the interior's swept envelope: float64 rows (x, y, z, radius) (`validation/envelope.py`)
    envelope: Mapped[bytes | None] = mapped_column(LargeBinary, nullable=True)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)


class TrajectoryTombstone(Base):
    """A record that a trajectory was deleted, for replicas to drop it from their index."""

    __tablename__ = "trajectory_tombstones"
    __table_args__ = ({"sqlite_autoincrement": True},)

    id: Mapped[int] = mapped_column(BigIntPK, primary_key=True, autoincrement=True)
    trajectory_id: Mapped[int] = mapped_column(BigInteger)
    model_id: Mapped[str] = mapped_column(String(64), index=True)
    deleted_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)


class TrajectoryCommit(Base):
    """One write of trajectories, logged in its own transaction: the ids it inserted lie in
    `first_id`..`last_id`. Replicas sync by reading this log (`services.catalog.index_store`)."""

    __tablename__ = "trajectory_commits"
    __table_args__ = ({"sqlite_autoincrement": True},)

    id: Mapped[int] = mapped_column(BigIntPK, primary_key=True, autoincrement=True)
    first_id: Mapped[int] = mapped_column(BigInteger)
    last_id: Mapped[int] = mapped_column(BigInteger)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, index=True)


class PlanEvent(Base):
    """One answered (or failed) plan request, for statistics and the dashboard."""

    __tablename__ = "plan_events"
    __table_args__ = (
        Index("ix_plan_events_robot_id_created_at", "robot_id", "created_at"),
        Index("ix_plan_events_model_id_created_at", "model_id", "created_at"),
        Index("ix_plan_events_status_created_at", "status", "created_at"),
        Index("ix_plan_events_requester_created_at", "requester", "created_at"),
        Index("ix_plan_events_trajectory_id_created_at", "trajectory_id", "created_at"),
        Index("uq_plan_events_record_key", "record_key", unique=True),
        {"sqlite_autoincrement": True},
    )

    id: Mapped[int] = mapped_column(BigIntPK, primary_key=True, autoincrement=True)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, index=True)
    robot_id: Mapped[str] = mapped_column(String(128))
    # Who `robot_id` is: a robot, or a seed job (robot_id `seed-job-<id>`); ids never tell.
    requester: Mapped[str] = mapped_column(String(16), server_default="robot")
    model_id: Mapped[str] = mapped_column(String(64))
    scene_hash: Mapped[str | None] = mapped_column(String(64))
    status: Mapped[str] = mapped_column(String(32))
    source: Mapped[str | None] = mapped_column(String(16))
    trajectory_id: Mapped[int | None] = mapped_column(BigInteger)
    candidates_tried: Mapped[int] = mapped_column(Integer, default=0)
    lookup_ms: Mapped[float] = mapped_column(Float, default=0.0)
    validate_ms: Mapped[float] = mapped_column(Float, default=0.0)
    plan_ms: Mapped[float] = mapped_column(Float, default=0.0)
    total_ms: Mapped[float] = mapped_column(Float, default=0.0)
    error: Mapped[str | None] = mapped_column(String(500))
    # The planner's random seed when the request planned (run it again with it to reproduce).
    seed: Mapped[int | None] = mapped_column(Integer)
    # Why each cached candidate was rejected: its first failing validation sample, the state
    # there and the pairs (or joints) at fault (`services/bookkeeping/rejections.py`); None:
    # none was.
    rejections: Mapped[list[dict[str, Any]] | None] = mapped_column(JSON)
    # The goal as a link's pose when the request gave one: {link, position, orientation,
    # position_tolerance, orientation_tolerance} (the model's base frame; the world for a
    # planar base); None: the goal was a state.
    goal_pose: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    # Set by the background bookkeeping writer: a write retried after its COMMIT reached the
    # database (only the answer was lost) is recognised by it instead of being counted twice.
    record_key: Mapped[str | None] = mapped_column(String(32))
    # What the goal was: "joint" (a state), "pose" (a link's pose); None: not recorded (older).
    goal_kind: Mapped[str | None] = mapped_column(String(16))


class PlanEventRollup(Base):
    """Plan events of one hour with one robot (and requester), model, source and status,
    summarised.

    Sums of the timings and a sparse latency histogram per timing (`services/stats/rollups.py`), so
    statistics over long windows read one row per hour and group instead of every event.
    """

    __tablename__ = "plan_event_rollups"

    id: Mapped[int] = mapped_column(BigIntPK, primary_key=True, autoincrement=True)
    bucket_start: Mapped[datetime] = mapped_column(UTCDateTime(), index=True)
    robot_id: Mapped[str] = mapped_column(String(128))
    requester: Mapped[str] = mapped_column(String(16), server_default="robot")
    model_id: Mapped[str] = mapped_column(String(64))
    source: Mapped[str | None] = mapped_column(String(16))
    status: Mapped[str] = mapped_column(String(32))
    goal_kind: Mapped[str | None] = mapped_column(String(16))  # as plan_events.goal_kind
    requests: Mapped[int] = mapped_column(Integer)
    lookup_ms: Mapped[float] = mapped_column(Float)
    validate_ms: Mapped[float] = mapped_column(Float)
    plan_ms: Mapped[float] = mapped_column(Float)
    total_ms: Mapped[float] = mapped_column(Float)
    histograms: Mapped[bytes] = mapped_column(LargeBinary)


class PlanEventRollupState(Base):
    """How far plan events are rolled up: every hour before `rolled_until` (a single row)."""

    __tablename__ = "plan_event_rollup_state"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    rolled_until: Mapped[datetime] = mapped_column(UTCDateTime())


class ApiKey(Base):
    """An API key (only its hash is stored) with a role and, for robots, the robots it may use."""

    __tablename__ = "api_keys"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    prefix: Mapped[str] = mapped_column(String(16), index=True)
    key_hash: Mapped[str] = mapped_column(String(128))
    role: Mapped[str] = mapped_column(String(16))
    robot_ids: Mapped[list[str]] = mapped_column(JSON, default=list)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)
    revoked_at: Mapped[datetime | None] = mapped_column(UTCDateTime())


class SeedJob(Base):
    """A pre-seeding job: its request, progress and which replica runs it (services/seeding/).

    Progress counts only the first `done` work items, all finished: a job resumed elsewhere
    starts at item `done`. A replica runs a job while it holds the lease (`lease_owner` until
    `lease_expires_at`, renewed by each progress write).
    """

    __tablename__ = "seed_jobs"
    __table_args__ = (
        Index("ix_seed_jobs_state_lease_expires_at", "state", "lease_expires_at"),
        {"sqlite_autoincrement": True},
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    name: Mapped[str | None] = mapped_column(String(200))
    model_id: Mapped[str] = mapped_column(String(64), ForeignKey("robot_models.id"), index=True)
    state: Mapped[str] = mapped_column(String(16))
    spec: Mapped[dict[str, Any]] = mapped_column(JSON)
    total: Mapped[int] = mapped_column(Integer)
    done: Mapped[int] = mapped_column(Integer, default=0)
    hits: Mapped[int] = mapped_column(Integer, default=0)
    planned: Mapped[int] = mapped_column(Integer, default=0)
    # Of the planned paths, those newly stored (the others were identical to a stored one);
    # None for jobs created before this counter existed.
    stored: Mapped[int | None] = mapped_column(Integer, default=0)
    failed: Mapped[int] = mapped_column(Integer, default=0)
    errors: Mapped[list[dict[str, Any]]] = mapped_column(JSON, default=list)
    message: Mapped[str | None] = mapped_column(String(500))
    lease_owner: Mapped[str | None] = mapped_column(String(128))
    lease_expires_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    eta_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)


class SeedJobScene(Base):
    """A scene of a seed job (canonical native form) and its hash, kept with the job so the
    trajectories it seeded can be shown in the scene they were planned in."""

    __tablename__ = "seed_job_scenes"
    __table_args__ = (UniqueConstraint("job_id", "position"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    job_id: Mapped[int] = mapped_column(Integer, ForeignKey("seed_jobs.id", ondelete="CASCADE"))
    position: Mapped[int] = mapped_column(Integer)  # the scene's index in the job
    hash: Mapped[str] = mapped_column(String(64), index=True)
    payload: Mapped[dict[str, Any]] = mapped_column(JSON)
