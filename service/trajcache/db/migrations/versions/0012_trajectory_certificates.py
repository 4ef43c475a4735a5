"""Certificates kept with trajectories: what validation proved, for later validations.

Revision ID: 0012
Revises: 0011
Create Date: 2026-11-27 23:40:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0012"
down_revision: str | Sequence[str] | None = "0011"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # Trajectories stored before this revision have none: their next valid verdict writes one.
    op.create_table(
        "trajectory_certificates",
        sa.Column("id", sa.BigInteger().with_variant(sa.Integer(), "sqlite"), nullable=False),
        sa.Column("trajectory_id", sa.BigInteger(), nullable=False),
        sa.Column("variant", sa.String(length=64), nullable=False),
        sa.Column("stamp", sa.String(length=64), nullable=False),
        sa.Column("path", sa.String(length=64), nullable=False),
        sa.Column("objects", sa.JSON(), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["trajectory_id"],
            ["trajectories.id"],
            name=op.f("fk_trajectory_certificates_trajectory_id_trajectories"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_trajectory_certificates")),
        sa.UniqueConstraint(
            "trajectory_id",
            "variant",
            "stamp",
            "path",
            name=op.f("uq_trajectory_certificates_trajectory_id_variant_stamp_path"),
        ),
        sqlite_autoincrement=True,
    )


def downgrade() -> None:
    op.drop_table("trajectory_certificates")
