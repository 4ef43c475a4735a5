"""Initial schema: models, robots, scenes, trajectories, tombstones, plan events, API keys.

Revision ID: 0001
Revises:
Create Date: 2026-11-21 08:45:51.997350+00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision: str = "0001"
down_revision: str | Sequence[str] | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

# BIGINT ids on PostgreSQL; on SQLite an INTEGER PRIMARY KEY (rowid) with AUTOINCREMENT so that
# ids are never reused and replicas can follow new rows by a high-water mark.
BigIntPK = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
Timestamp = sa.DateTime(timezone=True)


def upgrade() -> None:
    _models()
    _robots_and_scenes()
    _trajectories()
    _events_and_keys()


def _models() -> None:
    """Robot models and their files."""
    op.create_table(
        "robot_models",
        sa.Column("id", sa.String(length=64), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("base", sa.String(length=16), nullable=False),
        sa.Column("joint_names", sa.JSON(), nullable=False),
        sa.Column("urdf", sa.Text(), nullable=False),
        sa.Column("allowed_pairs", sa.JSON(), nullable=False),
        sa.Column("config", sa.JSON(), nullable=False),
        sa.Column("created_at", Timestamp, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_robot_models")),
    )

    op.create_table(
        "model_files",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("model_id", sa.String(length=64), nullable=False),
        sa.Column("path", sa.String(length=1024), nullable=False),
        sa.Column("sha256", sa.String(length=64), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(
            ["model_id"],
            ["robot_models.id"],
            name=op.f("fk_model_files_model_id_robot_models"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_model_files")),
        sa.UniqueConstraint("model_id", "path", name=op.f("uq_model_files_model_id_path")),
    )
    op.create_index(op.f("ix_model_files_model_id"), "model_files", ["model_id"])


def _robots_and_scenes() -> None:
    """Robots and their scene versions."""
    op.create_table(
        "robots",
        sa.Column("id", sa.String(length=128), nullable=False),
        sa.Column("model_id", sa.String(length=64), nullable=False),
        sa.Column("scene_version", sa.Integer(), nullable=True),
        sa.Column("created_at", Timestamp, nullable=False),
        sa.Column("updated_at", Timestamp, nullable=False),
        sa.ForeignKeyConstraint(
            ["model_id"], ["robot_models.id"], name=op.f("fk_robots_model_id_robot_models")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_robots")),
    )
    op.create_index(op.f("ix_robots_model_id"), "robots", ["model_id"])

    op.create_table(
        "scene_versions",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("robot_id", sa.String(length=128), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("hash", sa.String(length=64), nullable=False),
        sa.Column("payload", sa.JSON(), nullable=False),
        sa.Column("env", sa.JSON(), nullable=False),
        sa.Column("created_at", Timestamp, nullable=False),
        sa.ForeignKeyConstraint(
            ["robot_id"],
            ["robots.id"],
            name=op.f("fk_scene_versions_robot_id_robots"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_scene_versions")),
        sa.UniqueConstraint("robot_id", "version", name=op.f("uq_scene_versions_robot_id_version")),
    )
    op.create_index(op.f("ix_scene_versions_hash"), "scene_versions", ["hash"])


def _trajectories() -> None:
    """Trajectories and their tombstones."""
    op.create_table(
        "trajectories",
        sa.Column("id", BigIntPK, autoincrement=True, nullable=False),
        sa.Column("model_id", sa.String(length=64), nullable=False),
        sa.Column("source", sa.String(length=16), nullable=False),
        sa.Column("robot_id", sa.String(length=128), nullable=True),
        sa.Column("states", sa.LargeBinary(), nullable=False),
        sa.Column("n_states", sa.Integer(), nullable=False),
        sa.Column("dof", sa.Integer(), nullable=False),
        sa.Column("start", sa.JSON(), nullable=False),
        sa.Column("goal", sa.JSON(), nullable=False),
        sa.Column("start_x", sa.Float(), nullable=False),
        sa.Column("start_y", sa.Float(), nullable=False),
        sa.Column("goal_x", sa.Float(), nullable=False),
        sa.Column("goal_y", sa.Float(), nullable=False),
        sa.Column("scene_hash", sa.String(length=64), nullable=True),
        sa.Column("env", sa.JSON(), nullable=False),
        sa.Column("content_hash", sa.String(length=64), nullable=False),
        sa.Column("hits", sa.Integer(), nullable=False),
        sa.Column("failures", sa.Integer(), nullable=False),
        sa.Column("consecutive_failures", sa.Integer(), nullable=False),
        sa.Column("real_validations", sa.Integer(), nullable=False),
        sa.Column("last_used_at", Timestamp, nullable=True),
        sa.Column("last_validated_at", Timestamp, nullable=True),
        sa.Column("last_real_validated_at", Timestamp, nullable=True),
        sa.Column("planning_time_ms", sa.Float(), nullable=True),
        sa.Column("length", sa.Float(), nullable=True),
        sa.Column("quality", sa.JSON(), nullable=True),
        sa.Column("created_at", Timestamp, nullable=False),
        sa.ForeignKeyConstraint(
            ["model_id"], ["robot_models.id"], name=op.f("fk_trajectories_model_id_robot_models")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_trajectories")),
        sa.UniqueConstraint(
            "model_id", "content_hash", name=op.f("uq_trajectories_model_id_content_hash")
        ),
        sqlite_autoincrement=True,
    )
    op.create_index("ix_trajectories_model_id_id", "trajectories", ["model_id", "id"])
    op.create_index(
        "ix_trajectories_model_id_start_xy", "trajectories", ["model_id", "start_x", "start_y"]
    )

    op.create_table(
        "trajectory_tombstones",
        sa.Column("id", BigIntPK, autoincrement=True, nullable=False),
        sa.Column("trajectory_id", sa.BigInteger(), nullable=False),
        sa.Column("model_id", sa.String(length=64), nullable=False),
        sa.Column("deleted_at", Timestamp, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_trajectory_tombstones")),
        sqlite_autoincrement=True,
    )
    op.create_index(
        op.f("ix_trajectory_tombstones_model_id"), "trajectory_tombstones", ["model_id"]
    )


def _events_and_keys() -> None:
    """Plan events and API keys."""
    op.create_table(
        "plan_events",
        sa.Column("id", BigIntPK, autoincrement=True, nullable=False),
        sa.Column("created_at", Timestamp, nullable=False),
        sa.Column("robot_id", sa.String(length=128), nullable=False),
        sa.Column("model_id", sa.String(length=64), nullable=False),
        sa.Column("scene_hash", sa.String(length=64), nullable=True),
        sa.Column("status", sa.String(length=32), nullable=False),
        sa.Column("source", sa.String(length=16), nullable=True),
        sa.Column("trajectory_id", sa.BigInteger(), nullable=True),
        sa.Column("candidates_tried", sa.Integer(), nullable=False),
        sa.Column("lookup_ms", sa.Float(), nullable=False),
        sa.Column("validate_ms", sa.Float(), nullable=False),
        sa.Column("plan_ms", sa.Float(), nullable=False),
        sa.Column("total_ms", sa.Float(), nullable=False),
        sa.Column("error", sa.String(length=500), nullable=True),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_plan_events")),
        sqlite_autoincrement=True,
    )
    op.create_index(op.f("ix_plan_events_created_at"), "plan_events", ["created_at"])
    op.create_index("ix_plan_events_robot_id_created_at", "plan_events", ["robot_id", "created_at"])
    op.create_index("ix_plan_events_model_id_created_at", "plan_events", ["model_id", "created_at"])
    op.create_index("ix_plan_events_status_created_at", "plan_events", ["status", "created_at"])

    op.create_table(
        "api_keys",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("prefix", sa.String(length=16), nullable=False),
        sa.Column("key_hash", sa.String(length=128), nullable=False),
        sa.Column("role", sa.String(length=16), nullable=False),
        sa.Column("robot_ids", sa.JSON(), nullable=False),
        sa.Column("created_at", Timestamp, nullable=False),
        sa.Column("revoked_at", Timestamp, nullable=True),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_api_keys")),
    )
    op.create_index(op.f("ix_api_keys_prefix"), "api_keys", ["prefix"])


def downgrade() -> None:
    # Dropping a table drops its indexes; children before parents.
    for table in (
        "api_keys",
        "plan_events",
        "trajectory_tombstones",
        "trajectories",
        "scene_versions",
        "robots",
        "model_files",
        "robot_models",
    ):
        op.drop_table(table)
