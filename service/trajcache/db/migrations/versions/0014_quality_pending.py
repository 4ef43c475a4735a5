"""Imported trajectories get their quality in the background: `quality_pending` marks them.

Revision ID: 0014
Revises: 0013
Create Date: 2026-11-28 01:50:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0014"
down_revision: str | Sequence[str] | None = "0013"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # Rows stored before this revision had their quality computed when they were stored. A
    # plain ADD COLUMN (no batch copy): SQLite keeps the table's AUTOINCREMENT.
    op.add_column(
        "trajectories",
        sa.Column("quality_pending", sa.Boolean(), nullable=False, server_default=sa.false()),
    )
    op.create_index("ix_trajectories_quality_pending", "trajectories", ["quality_pending"])


def downgrade() -> None:
    op.drop_index("ix_trajectories_quality_pending", table_name="trajectories")
    with op.batch_alter_table("trajectories", table_kwargs={"sqlite_autoincrement": True}) as batch:
        batch.drop_column("quality_pending")
