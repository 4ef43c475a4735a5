"""Pre-seeding: seed jobs (state, progress, lease) and the kind of a robot (real or sim).

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-23 09:00:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0004"
down_revision: str | Sequence[str] | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

Timestamp = sa.DateTime(timezone=True)


def upgrade() -> None:
    with op.batch_alter_table("robots") as batch:
        batch.add_column(
            sa.Column("kind", sa.String(length=8), server_default="real", nullable=False)
        )
    op.create_table(
        "seed_jobs",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=True),
        sa.Column("model_id", sa.String(length=64), nullable=False),
        sa.Column("state", sa.String(length=16), nullable=False),
        sa.Column("spec", sa.JSON(), nullable=False),
        sa.Column("total", sa.Integer(), nullable=False),
        sa.Column("done", sa.Integer(), nullable=False),
        sa.Column("hits", sa.Integer(), nullable=False),
        sa.Column("planned", sa.Integer(), nullable=False),
        sa.Column("failed", sa.Integer(), nullable=False),
        sa.Column("errors", sa.JSON(), nullable=False),
        sa.Column("message", sa.String(length=500), nullable=True),
        sa.Column("lease_owner", sa.String(length=128), nullable=True),
        sa.Column("lease_expires_at", Timestamp, nullable=True),
        sa.Column("eta_at", Timestamp, nullable=True),
        sa.Column("created_at", Timestamp, nullable=False),
        sa.Column("started_at", Timestamp, nullable=True),
        sa.Column("finished_at", Timestamp, nullable=True),
        sa.Column("updated_at", Timestamp, nullable=False),
        sa.ForeignKeyConstraint(
            ["model_id"], ["robot_models.id"], name=op.f("fk_seed_jobs_model_id_robot_models")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_seed_jobs")),
        sqlite_autoincrement=True,
    )
    op.create_index(op.f("ix_seed_jobs_model_id"), "seed_jobs", ["model_id"])
    op.create_index(
        "ix_seed_jobs_state_lease_expires_at", "seed_jobs", ["state", "lease_expires_at"]
    )


def downgrade() -> None:
    op.drop_index("ix_seed_jobs_state_lease_expires_at", table_name="seed_jobs")
    op.drop_index(op.f("ix_seed_jobs_model_id"), table_name="seed_jobs")
    op.drop_table("seed_jobs")
    with op.batch_alter_table("robots") as batch:
        batch.drop_column("kind")
