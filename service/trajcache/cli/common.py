"""What the command groups share: the error console, `--database-url`, settings and sessions."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from trajcache.core.config import Settings

DatabaseUrlOption = Annotated[
    str | None,
    typer.Option(
        "--database-url", metavar="URL", help="Database (default: TRAJCACHE_DATABASE_URL)."
    ),
]


def err_console() -> Console:
    """The console of messages and progress (stderr; stdout is for results)."""
    return Console(stderr=True)


def fail(exc: Exception) -> typer.Exit:
    """Print `exc` as an error; the exit (status 2) to raise."""
    err_console().print(f"[red]error:[/red] {exc}")
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


@contextmanager
def open_session(settings: Settings, *, migrate: bool = False) -> Iterator[Session]:
    """A session of the settings' database (upgraded to the latest schema first if `migrate`)."""
    from trajcache.db.session import make_engine, make_sessionmaker

    if migrate:
        from trajcache.db import migrate as db_migrate

        db_migrate.upgrade(settings.database_url)
    engine = make_engine(settings.database_url, pool_size=2)
    try:
        with make_sessionmaker(engine)() as session:
            yield session
    finally:
        engine.dispose()
