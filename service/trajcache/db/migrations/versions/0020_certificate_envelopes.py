"""Certificates keep their path interior's swept envelope.

Revision ID: 0020
Revises: 0019
Create Date: 2026-11-30 04:00:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0020"
down_revision: str | Sequence[str] | None = "0019"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # Certificates written before have none: an object they never saw is proved, as it was.
    with op.batch_alter_table("trajectory_certificates") as batch:
        batch.add_column(sa.Column("envelope", sa.LargeBinary(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("trajectory_certificates") as batch:
        batch.drop_column("envelope")
