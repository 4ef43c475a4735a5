"""Trajectory quality columns; acceleration/jerk limits and end-effector link on robot models.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-22 09:00:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0002"
down_revision: str | Sequence[str] | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("robot_models") as batch:
        batch.add_column(sa.Column("acceleration_limits", sa.JSON(), nullable=True))
        batch.add_column(sa.Column("jerk_limits", sa.JSON(), nullable=True))
        batch.add_column(sa.Column("end_effector_link", sa.String(length=200), nullable=True))
    with op.batch_alter_table("trajectories") as batch:
        batch.add_column(sa.Column("ee_length", sa.Float(), nullable=True))
        batch.add_column(sa.Column("min_clearance", sa.Float(), nullable=True))
        batch.add_column(sa.Column("duration_s", sa.Float(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("trajectories") as batch:
        batch.drop_column("duration_s")
        batch.drop_column("min_clearance")
        batch.drop_column("ee_length")
    with op.batch_alter_table("robot_models") as batch:
        batch.drop_column("end_effector_link")
        batch.drop_column("jerk_limits")
        batch.drop_column("acceleration_limits")
