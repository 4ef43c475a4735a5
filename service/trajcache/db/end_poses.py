"""The index of trajectories' end poses (`services.catalog.end_poses` writes and reads it)."""

from __future__ import annotations

from sqlalchemy import BigInteger, Float, ForeignKey, Index, SmallInteger, String
from sqlalchemy.orm import Mapped, mapped_column

from trajcache.db.base import Base
from trajcache.db.models import BigIntPK


class TrajectoryEndPose(Base):
    """The pose of an indexed link (relative to the root link) at one end of a trajectory;
    deleted with its trajectory and with its model."""

    __tablename__ = "trajectory_end_poses"
    __table_args__ = (
        # covering a search by position: no table row is read for an end outside the radius
        Index(
            "ix_trajectory_end_poses_model_id_link_xyz",
            *("model_id", "link", "x", "y", "z", "end", "trajectory_id"),
        ),
        {"sqlite_autoincrement": True},
    )

    id: Mapped[int] = mapped_column(BigIntPK, primary_key=True, autoincrement=True)
    trajectory_id: Mapped[int] = mapped_column(
        BigInteger, ForeignKey("trajectories.id", ondelete="CASCADE"), index=True
    )
    model_id: Mapped[str] = mapped_column(
        String(64), ForeignKey("robot_models.id", ondelete="CASCADE")
    )
    link: Mapped[str] = mapped_column(String(200))
    end: Mapped[int] = mapped_column(SmallInteger)  # 0: the start state, 1: the goal state
    x: Mapped[float] = mapped_column(Float)
    y: Mapped[float] = mapped_column(Float)
    z: Mapped[float] = mapped_column(Float)
    qx: Mapped[float] = mapped_column(Float)
    qy: Mapped[float] = mapped_column(Float)
    qz: Mapped[float] = mapped_column(Float)
    qw: Mapped[float] = mapped_column(Float)


class EndPoseBacklog(Base):
    """A trajectory stored before end poses were indexed, waiting for its index rows
    (`services.maintenance.backfill` works the backlog off in the background)."""

    __tablename__ = "end_pose_backlog"

    trajectory_id: Mapped[int] = mapped_column(
        BigInteger,
        ForeignKey("trajectories.id", ondelete="CASCADE"),
        primary_key=True,
        autoincrement=False,
    )
