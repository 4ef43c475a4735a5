"""Plan events and their rollups record who asked: a robot or a seed job.

Revision ID: 0008
Revises: 0007
Create Date: 2026-11-27 10:00:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0008"
down_revision: str | Sequence[str] | None = "0007"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

TABLES = ("plan_events", "plan_event_rollups")


def upgrade() -> None:
    # Existing rows were robots', except those of the seed jobs, whose plan events were recorded
    # with the robot id `seed-job-<id>`: a name a robot may have too, so only the names of seed
    # jobs that exist are taken for theirs.
    jobs = sa.table("seed_jobs", sa.column("id", sa.Integer))
    callers = sa.select(sa.literal("seed-job-") + sa.cast(jobs.c.id, sa.String(20)))
    for name in TABLES:
        op.add_column(
            name,
            sa.Column("requester", sa.String(length=16), server_default="robot", nullable=False),
        )
        rows = sa.table(name, sa.column("robot_id", sa.String), sa.column("requester", sa.String))
        op.execute(
            rows.update()
            .where(rows.c.robot_id.like("seed-job-%"), rows.c.robot_id.in_(callers))
            .values(requester="seed_job")
        )
    op.create_index(
        "ix_plan_events_requester_created_at", "plan_events", ["requester", "created_at"]
    )


def downgrade() -> None:
    op.drop_index("ix_plan_events_requester_created_at", table_name="plan_events")
    for name in TABLES:
        with op.batch_alter_table(name) as batch:
            batch.drop_column("requester")
