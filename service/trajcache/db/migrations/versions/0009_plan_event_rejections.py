"""A plan event records why each cached candidate was rejected: where it failed and on what.

Revision ID: 0009
Revises: 0008
Create Date: 2026-11-27 10:00:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0009"
down_revision: str | Sequence[str] | None = "0008"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # A nullable column: a plain ALTER TABLE on both databases, existing rows untouched.
    op.add_column("plan_events", sa.Column("rejections", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("plan_events") as batch:
        batch.drop_column("rejections")
