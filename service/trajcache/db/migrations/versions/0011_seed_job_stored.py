"""A seed job counts the planned paths it newly stored apart from those already stored.

Revision ID: 0011
Revises: 0010
Create Date: 2026-11-27 23:30:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0011"
down_revision: str | Sequence[str] | None = "0010"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # A nullable column: a plain ALTER TABLE on both databases; jobs created before it stay
    # null (their planned paths were not told apart).
    op.add_column("seed_jobs", sa.Column("stored", sa.Integer(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("seed_jobs") as batch:
        batch.drop_column("stored")
