"""A seed job keeps its scenes, so the trajectories it seeded can be shown in them.

Revision ID: 0010
Revises: 0009
Create Date: 2026-11-27 12:00:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0010"
down_revision: str | Sequence[str] | None = "0009"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # Jobs created before this revision keep no scenes: their trajectories' scenes stay unknown.
    op.create_table(
        "seed_job_scenes",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("job_id", sa.Integer(), nullable=False),
        sa.Column("position", sa.Integer(), nullable=False),
        sa.Column("hash", sa.String(length=64), nullable=False),
        sa.Column("payload", sa.JSON(), nullable=False),
        sa.ForeignKeyConstraint(
            ["job_id"],
            ["seed_jobs.id"],
            name=op.f("fk_seed_job_scenes_job_id_seed_jobs"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_seed_job_scenes")),
        sa.UniqueConstraint("job_id", "position", name=op.f("uq_seed_job_scenes_job_id_position")),
    )
    op.create_index(op.f("ix_seed_job_scenes_hash"), "seed_job_scenes", ["hash"])


def downgrade() -> None:
    op.drop_index(op.f("ix_seed_job_scenes_hash"), table_name="seed_job_scenes")
    op.drop_table("seed_job_scenes")
