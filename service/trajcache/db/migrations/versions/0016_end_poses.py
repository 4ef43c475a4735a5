"""The index of trajectories' end poses, its backlog, and the goal kind of plan events (and of
their hourly rollups).

Revision ID: 0016
Revises: 0015
Create Date: 2026-11-28 04:30:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0016"
down_revision: str | Sequence[str] | None = "0015"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_POSE = ("x", "y", "z", "qx", "qy", "qz", "qw")


def upgrade() -> None:
    op.create_table(
        "trajectory_end_poses",
        sa.Column("id", sa.BigInteger().with_variant(sa.Integer(), "sqlite"), nullable=False),
        sa.Column("trajectory_id", sa.BigInteger(), nullable=False),
        sa.Column("model_id", sa.String(length=64), nullable=False),
        sa.Column("link", sa.String(length=200), nullable=False),
        sa.Column("end", sa.SmallInteger(), nullable=False),
        *(sa.Column(name, sa.Float(), nullable=False) for name in _POSE),
        sa.ForeignKeyConstraint(
            ["trajectory_id"],
            ["trajectories.id"],
            name=op.f("fk_trajectory_end_poses_trajectory_id_trajectories"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["model_id"],
            ["robot_models.id"],
            name=op.f("fk_trajectory_end_poses_model_id_robot_models"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_trajectory_end_poses")),
        sqlite_autoincrement=True,
    )
    op.create_index(
        "ix_trajectory_end_poses_model_id_link_xyz",
        "trajectory_end_poses",
        ["model_id", "link", "x", "y", "z", "end", "trajectory_id"],
    )
    op.create_index(
        op.f("ix_trajectory_end_poses_trajectory_id"), "trajectory_end_poses", ["trajectory_id"]
    )
    op.create_table(
        "end_pose_backlog",
        sa.Column("trajectory_id", sa.BigInteger(), autoincrement=False, nullable=False),
        sa.ForeignKeyConstraint(
            ["trajectory_id"],
            ["trajectories.id"],
            name=op.f("fk_end_pose_backlog_trajectory_id_trajectories"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("trajectory_id", name=op.f("pk_end_pose_backlog")),
    )
    # Trajectories stored so far get their index rows in the background (the service's
    # backfill thread works the backlog off), not here: that takes each model's kinematics.
    op.execute("INSERT INTO end_pose_backlog (trajectory_id) SELECT id FROM trajectories")
    # The goal kind of earlier plan events was not recorded: it stays null ("unknown").
    op.add_column("plan_events", sa.Column("goal_kind", sa.String(length=16), nullable=True))
    op.add_column("plan_event_rollups", sa.Column("goal_kind", sa.String(length=16), nullable=True))


def downgrade() -> None:
    for table in ("plan_event_rollups", "plan_events"):
        with op.batch_alter_table(table) as batch:
            batch.drop_column("goal_kind")
    op.drop_table("end_pose_backlog")
    op.drop_index(op.f("ix_trajectory_end_poses_trajectory_id"), table_name="trajectory_end_poses")
    op.drop_index("ix_trajectory_end_poses_model_id_link_xyz", table_name="trajectory_end_poses")
    op.drop_table("trajectory_end_poses")
