"""Certificates keep the clearance their path's interior was proved to have from each object.

Revision ID: 0019
Revises: 0018
Create Date: 2026-11-29 16:20:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0019"
down_revision: str | Sequence[str] | None = "0018"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # Certificates written before have none: a moved object is proved again, as it was.
    with op.batch_alter_table("trajectory_certificates") as batch:
        batch.add_column(sa.Column("clearances", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("trajectory_certificates") as batch:
        batch.drop_column("clearances")
