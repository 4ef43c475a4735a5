"""A robot may hold joints outside the planning joints otherwise than its model does.

Revision ID: 0006
Revises: 0005
Create Date: 2026-11-25 14:00:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0006"
down_revision: str | Sequence[str] | None = "0005"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # A nullable column: a plain ALTER TABLE on both databases, existing rows untouched.
    op.add_column("robots", sa.Column("joint_values", sa.Text(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("robots") as batch:
        batch.drop_column("joint_values")
