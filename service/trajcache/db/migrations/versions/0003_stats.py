"""Statistics: hourly plan-event rollups, their progress row, and plan events by trajectory.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-21 10:00:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0003"
down_revision: str | Sequence[str] | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

BigIntPK = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
Timestamp = sa.DateTime(timezone=True)


def upgrade() -> None:
    # A trajectory's usage history: its most recent plan events.
    op.create_index(
        "ix_plan_events_trajectory_id_created_at", "plan_events", ["trajectory_id", "created_at"]
    )

    op.create_table(
        "plan_event_rollups",
        sa.Column("id", BigIntPK, autoincrement=True, nullable=False),
        sa.Column("bucket_start", Timestamp, nullable=False),
        sa.Column("robot_id", sa.String(length=128), nullable=False),
        sa.Column("model_id", sa.String(length=64), nullable=False),
        sa.Column("source", sa.String(length=16), nullable=True),
        sa.Column("status", sa.String(length=32), nullable=False),
        sa.Column("requests", sa.Integer(), nullable=False),
        sa.Column("lookup_ms", sa.Float(), nullable=False),
        sa.Column("validate_ms", sa.Float(), nullable=False),
        sa.Column("plan_ms", sa.Float(), nullable=False),
        sa.Column("total_ms", sa.Float(), nullable=False),
        sa.Column("histograms", sa.LargeBinary(), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_plan_event_rollups")),
    )
    op.create_index(
        op.f("ix_plan_event_rollups_bucket_start"), "plan_event_rollups", ["bucket_start"]
    )

    op.create_table(
        "plan_event_rollup_state",
        sa.Column("id", sa.Integer(), autoincrement=False, nullable=False),
        sa.Column("rolled_until", Timestamp, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_plan_event_rollup_state")),
    )


def downgrade() -> None:
    op.drop_table("plan_event_rollup_state")
    op.drop_table("plan_event_rollups")
    op.drop_index("ix_plan_events_trajectory_id_created_at", table_name="plan_events")
