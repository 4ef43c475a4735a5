"""`trajcache keys create|list|revoke`: manage API keys in the configured database."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table
from sqlalchemy.orm import Session

from trajcache.services.errors import ServiceError

app = typer.Typer(help="Create, list and revoke API keys.", no_args_is_help=True)


@contextmanager
def _session() -> Iterator[Session]:
    from trajcache.core.config import Settings
    from trajcache.db import migrate
    from trajcache.db.session import make_engine, make_sessionmaker

    settings = Settings()
    migrate.upgrade(settings.database_url)
    engine = make_engine(settings.database_url, pool_size=1)
    try:
        with make_sessionmaker(engine)() as session:
            yield session
    finally:
        engine.dispose()


def _fail(exc: ServiceError) -> typer.Exit:
    Console(stderr=True).print(f"[red]error:[/red] {exc}")
    return typer.Exit(2)


@app.command()
def create(
    name: Annotated[str, typer.Option(help="Who or what the key is for.")],
    role: Annotated[str, typer.Option(help="robot, seeder or admin.")],
    robot: Annotated[
        list[str] | None,
        typer.Option("--robot", help="A robot id a robot key may use (repeat for several)."),
    ] = None,
) -> None:
    """Create a key and print it once; only its hash is stored."""
    from trajcache.services.keys import create_key

    with _session() as session:
        try:
            info, secret = create_key(session=session, name=name, role=role, robot_ids=robot)
        except ServiceError as exc:
            raise _fail(exc) from None
    Console(stderr=True).print(
        f"created {info.role} key #{info.id} ({info.prefix}) for {info.name!r}; "
        "store it now, it cannot be shown again:"
    )
    typer.echo(secret)


@app.command("list")
def list_command(
    all_keys: Annotated[bool, typer.Option("--all", help="Include revoked keys.")] = False,
) -> None:
    """List keys (never their secrets)."""
    from trajcache.services.keys import list_keys

    with _session() as session:
        keys = list_keys(session=session, include_revoked=all_keys)
    table = Table("id", "prefix", "role", "name", "robots", "created", "revoked")
    for k in keys:
        table.add_row(
            str(k.id),
            k.prefix,
            k.role,
            k.name,
            ", ".join(k.robot_ids),
            k.created_at.isoformat(timespec="seconds"),
            k.revoked_at.isoformat(timespec="seconds") if k.revoked_at else "",
        )
    Console().print(table)


@app.command()
def revoke(key: Annotated[str, typer.Argument(help="Key id or prefix.")]) -> None:
    """Revoke a key; services stop accepting it within auth_cache_ttl_s."""
    from trajcache.services.keys import revoke_key

    with _session() as session:
        try:
            info = revoke_key(session=session, key=key)
        except ServiceError as exc:
            raise _fail(exc) from None
    Console(stderr=True).print(f"revoked key #{info.id} ({info.prefix}, {info.name!r})")
