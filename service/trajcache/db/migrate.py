"""Programmatic Alembic: upgrade a database to a revision, read and check its revision."""

from __future__ import annotations

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Engine
from sqlalchemy.exc import DBAPIError

from trajcache.db.session import make_engine, shown_url, sqlite_file

# The migrations ship inside the package (trajcache/db/migrations/), found as a package resource
# wherever it is installed: an editable install, a wheel, a container image.
SCRIPT_LOCATION = "trajcache.db:migrations"


class DatabaseNotReady(Exception):
    """The database is missing, unreachable or not at this release's schema; the message says
    which, and how to migrate it."""


def database_error(exc: DBAPIError) -> str:
    """The first line of what the database driver said."""
    lines = str(exc.orig).strip().splitlines() if exc.orig is not None else []
    return lines[0] if lines else type(exc).__name__


def alembic_config(url: str) -> Config:
    """An Alembic Config for the package's migrations, targeting `url`."""
    config = Config()
    config.set_main_option("script_location", SCRIPT_LOCATION)
    config.set_main_option("path_separator", "os")
    config.attributes["url"] = url
    return config


def upgrade(url: str, revision: str = "head") -> None:
    """Apply migrations to the database at `url` up to `revision` (a SQLite file's directory is
    created)."""
    path = sqlite_file(url)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
    command.upgrade(alembic_config(url), revision)


def downgrade(url: str, revision: str) -> None:
    """Revert migrations on the database at `url` down to `revision` ("base" for all)."""
    command.downgrade(alembic_config(url), revision)


def current_revision(url: str) -> str | None:
    """The revision the database at `url` is at, or None when it has no migrations applied."""
    engine: Engine = make_engine(url, pool_size=1)
    try:
        with engine.connect() as conn:
            return MigrationContext.configure(conn).get_current_revision()
    finally:
        engine.dispose()


def require_schema(url: str) -> None:
    """Raise DatabaseNotReady unless the database at `url` is at the latest revision.

    Nothing is created: a SQLite file that is not there is reported, not made empty."""
    shown = shown_url(url)
    how = f"create or upgrade it with `trajcache migrate --database-url {shown}`"
    path = sqlite_file(url)
    if path is not None and not path.is_file():
        raise DatabaseNotReady(f"no trajcache database at {path}; {how}")
    try:
        revision = current_revision(url)
    except DBAPIError as exc:
        raise DatabaseNotReady(f"cannot read the database {shown}: {database_error(exc)}") from None
    script = ScriptDirectory.from_config(alembic_config(url))
    head = script.get_current_head()
    if revision is None:
        raise DatabaseNotReady(f"the database {shown} has no trajcache schema; {how}")
    if revision == head:
        return
    if revision not in {s.revision for s in script.walk_revisions()}:
        raise DatabaseNotReady(
            f"the database {shown} is at schema revision {revision}, which this trajcache does "
            f"not know (a newer release migrated it); its latest is {head}"
        )
    raise DatabaseNotReady(
        f"the database {shown} is at schema revision {revision}, not {head}; {how}"
    )
