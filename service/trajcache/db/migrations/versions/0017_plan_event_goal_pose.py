"""A plan event keeps the goal pose its request gave (the dashboard draws it).

Revision ID: 0017
Revises: 0016
Create Date: 2026-11-28 04:40:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0017"
down_revision: str | Sequence[str] | None = "0016"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # Events recorded before this revision keep no goal pose (null). A plain ADD COLUMN (no
    # batch copy): SQLite keeps the table's AUTOINCREMENT.
    op.add_column("plan_events", sa.Column("goal_pose", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("plan_events", table_kwargs={"sqlite_autoincrement": True}) as batch:
        batch.drop_column("goal_pose")
