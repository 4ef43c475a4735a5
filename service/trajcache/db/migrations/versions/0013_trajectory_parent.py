"""A repaired trajectory names its parent, the cached path it was mended from.

Revision ID: 0013
Revises: 0012
Create Date: 2026-11-27 23:50:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0013"
down_revision: str | Sequence[str] | None = "0012"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # Trajectories stored before this revision were never repairs: their parent stays null.
    with op.batch_alter_table("trajectories") as batch:
        batch.add_column(sa.Column("parent_id", sa.BigInteger(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("trajectories") as batch:
        batch.drop_column("parent_id")
