"""What the command groups share: the error console, `--database-url`, settings and sessions."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.markup import escape

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from trajcache.core.config import Settings

DatabaseUrlOption = Annotated[
    str | None,
    typer.Option(
        "--database-url",
        metavar="URL",
        help="Database (default: TRAJCACHE_DATABASE_URL); a relative SQLite path is in "
        "TRAJCACHE_DATA_DIR.",
    ),
]


def err_console() -> Console:
    """The console of messages and progress (stderr; stdout is for results)."""
    return Console(stderr=True)


def fail(exc: Exception) -> typer.Exit:
    """Print `exc` as an error on one line; the exit (status 2) to raise."""
    err_console().print(f"[red]error:[/red] {escape(str(exc))}", soft_wrap=True)
    return typer.Exit(2)


def load_settings(database_url: str | None = None) -> Settings:
    """The TRAJCACHE_* settings, `database_url` replacing the configured one; exit 2 if invalid."""
    from pydantic import ValidationError

    from trajcache.core.config import Settings

    try:
        settings = Settings()
        if database_url is not None:
            settings = Settings(database_url=database_url)
    except ValidationError as exc:
        err_console().print(f"[red]invalid TRAJCACHE_* settings:[/red] {exc}")
        raise typer.Exit(2) from None
    return settings


def upgrade_database(url: str, revision: str = "head") -> None:
    """Migrate the database at `url` (created if it is a SQLite file); exit 2 if it cannot be."""
    from sqlalchemy.exc import DBAPIError

    from trajcache.db import migrate as db_migrate
    from trajcache.db.session import shown_url

    try:
        db_migrate.upgrade(url, revision)
    except DBAPIError as exc:
        reason = f"cannot migrate the database {shown_url(url)}: {db_migrate.database_error(exc)}"
        raise fail(RuntimeError(reason)) from None


def require_database(url: str) -> None:
    """Exit 2 with one line saying how to migrate it unless the database at `url` is ready."""
    from trajcache.db.migrate import DatabaseNotReady, require_schema

    try:
        require_schema(url)
    except DatabaseNotReady as exc:
        raise fail(exc) from None


@contextmanager
def open_session(settings: Settings, *, migrate: bool = False) -> Iterator[Session]:
    """A session of the settings' database: upgraded to the latest schema first if `migrate`,
    else required to be there at it (nothing is created)."""
    from trajcache.db.session import make_engine, make_sessionmaker

    if migrate:
        upgrade_database(settings.database_url)
    else:
        require_database(settings.database_url)
    engine = make_engine(settings.database_url, pool_size=2)
    try:
        with make_sessionmaker(engine)() as session:
            yield session
    finally:
        engine.dispose()
