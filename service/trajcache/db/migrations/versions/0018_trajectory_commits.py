"""The trajectory commit log: one row per write of trajectories, read by replicas' syncs.

Revision ID: 0018
Revises: 0017
Create Date: 2026-11-29 05:00:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0018"
down_revision: str | Sequence[str] | None = "0017"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

BigIntPK = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
Timestamp = sa.DateTime(timezone=True)


def upgrade() -> None:
    # Trajectories stored before this revision have no log row: a replica loads every committed
    # row of a model when it first needs its index, so only later writes need one.
    op.create_table(
        "trajectory_commits",
        sa.Column("id", BigIntPK, autoincrement=True, nullable=False),
        sa.Column("first_id", sa.BigInteger(), nullable=False),
        sa.Column("last_id", sa.BigInteger(), nullable=False),
        sa.Column("created_at", Timestamp, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_trajectory_commits")),
        sqlite_autoincrement=True,
    )
    op.create_index(op.f("ix_trajectory_commits_created_at"), "trajectory_commits", ["created_at"])


def downgrade() -> None:
    op.drop_index(op.f("ix_trajectory_commits_created_at"), table_name="trajectory_commits")
    op.drop_table("trajectory_commits")
