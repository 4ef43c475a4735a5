"""The store of Cartesian path answers.

Revision ID: 0015
Revises: 0014
Create Date: 2026-11-28 02:10:00.000000+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0015"
down_revision: str | Sequence[str] | None = "0014"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # A new store: nothing earlier to carry over.
    op.create_table(
        "cartesian_paths",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("model_id", sa.String(length=64), nullable=False),
        sa.Column("link", sa.String(length=200), nullable=False),
        sa.Column("params", sa.String(length=64), nullable=False),
        sa.Column("waypoints", sa.JSON(), nullable=False),
        sa.Column("start", sa.JSON(), nullable=False),
        sa.Column("states", sa.JSON(), nullable=False),
        sa.Column("line_of", sa.JSON(), nullable=False),
        sa.ForeignKeyConstraint(
            ["model_id"],
            ["robot_models.id"],
            name=op.f("fk_cartesian_paths_model_id_robot_models"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_cartesian_paths")),
        sqlite_autoincrement=True,
    )
    op.create_index(
        "ix_cartesian_paths_model_id_link_params",
        "cartesian_paths",
        ["model_id", "link", "params"],
    )


def downgrade() -> None:
    op.drop_index("ix_cartesian_paths_model_id_link_params", table_name="cartesian_paths")
    op.drop_table("cartesian_paths")
