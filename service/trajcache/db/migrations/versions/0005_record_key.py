"""Plan events written by the bookkeeping writer carry a unique record key.

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-25 10:00:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0005"
down_revision: str | Sequence[str] | None = "0004"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # A nullable column: a plain ALTER TABLE on both databases, existing rows untouched.
    op.add_column("plan_events", sa.Column("record_key", sa.String(length=32), nullable=True))
    op.create_index("uq_plan_events_record_key", "plan_events", ["record_key"], unique=True)


def downgrade() -> None:
    op.drop_index("uq_plan_events_record_key", table_name="plan_events")
    with op.batch_alter_table("plan_events") as batch:
        batch.drop_column("record_key")
