"""Alembic environment: migrates the trajcache schema on SQLite or PostgreSQL.

The URL comes from `config.attributes["url"]` (set by trajcache.db.migrate), then
`alembic -x url=...`, then Settings().database_url (TRAJCACHE_DATABASE_URL). A connection in
`config.attributes["connection"]` is used as is. With PostgreSQL, `?options=-csearch_path%3D...`
in the URL puts the tables and `alembic_version` in that schema.
"""

from __future__ import annotations

from logging.config import fileConfig
from typing import Any, Literal

from alembic import context
from alembic.autogenerate.api import AutogenContext
from sqlalchemy import Connection, create_engine, pool, text
from sqlalchemy.types import TypeDecorator

from trajcache.db import cartesian, end_poses, models  # noqa: F401  (registers the tables on Base.metadata)
from trajcache.db.base import Base

config = context.config
target_metadata = Base.metadata

# Configure logging only from the alembic command line, never inside the service or tests.
if config.cmd_opts is not None and config.config_file_name is not None:
    fileConfig(config.config_file_name, disable_existing_loggers=False)


def database_url() -> str:
    """The URL to migrate, by precedence: attributes, `-x url=`, settings."""
    url = config.attributes.get("url") or context.get_x_argument(as_dictionary=True).get("url")
    if not url:
        from trajcache.core.config import Settings

        url = Settings().database_url
    if url.startswith("postgresql://"):
        url = "postgresql+psycopg://" + url[len("postgresql://") :]
    return str(url)


def render_item(type_: str, obj: Any, autogen_context: AutogenContext) -> str | Literal[False]:
    """Render custom column types (e.g. UTCDateTime) as their portable SQLAlchemy type."""
    if type_ == "type" and isinstance(obj, TypeDecorator):
        return f"sa.{obj.impl!r}"
    return False


def configure(connection: Connection | None = None, url: str | None = None) -> None:
    context.configure(
        connection=connection,
        url=url,
        target_metadata=target_metadata,
        compare_type=True,
        render_item=render_item,
        render_as_batch=True,  # SQLite cannot ALTER most things; batch mode copies the table
        literal_binds=connection is None,
        dialect_opts={"paramstyle": "named"} if connection is None else None,
    )


def run_on_connection(connection: Connection) -> None:
    configure(connection=connection)
    with context.begin_transaction():
        context.run_migrations()
    if connection.dialect.name == "sqlite":
        # Foreign keys are off here (batch mode drops and recreates tables); check afterwards.
        problems = connection.execute(text("PRAGMA foreign_key_check")).fetchall()
        if problems:
            raise RuntimeError(f"foreign key violations after migration: {problems[:10]}")


def run_migrations_offline() -> None:
    configure(url=database_url())
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    connection = config.attributes.get("connection")
    if connection is not None:
        run_on_connection(connection)
        return
    engine = create_engine(database_url(), poolclass=pool.NullPool)
    try:
        with engine.connect() as conn:
            run_on_connection(conn)
            conn.commit()
    finally:
        engine.dispose()


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()
