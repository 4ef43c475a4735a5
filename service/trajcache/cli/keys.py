"""`trajcache keys create|list|revoke`: manage API keys in the database (`--database-url`)."""

from __future__ import annotations

from typing import Annotated

import typer
from rich.console import Console
from rich.table import Column, Table

from trajcache.cli.common import DatabaseUrlOption, err_console, fail, load_settings, open_session
from trajcache.cli.help import TidyCommand, TidyGroup
from trajcache.services.catalog.keys import Role
from trajcache.services.errors import ServiceError

app = typer.Typer(cls=TidyGroup, help="Create, list and revoke API keys.", no_args_is_help=True)


@app.command(cls=TidyCommand)
def create(
    name: Annotated[str, typer.Option(metavar="NAME", help="Who or what the key is for.")],
    role: Annotated[Role, typer.Option(help="What the key may do.")],
    robot: Annotated[
        list[str] | None,
        typer.Option(
            "--robot",
            metavar="ROBOT_ID",
            help="A robot id a robot key may use (repeat for several).",
        ),
    ] = None,
    database_url: DatabaseUrlOption = None,
) -> None:
    """Create a key and print it once; only its hash is stored."""
    from trajcache.services.catalog.keys import create_key

    with open_session(load_settings(database_url), migrate=True) as session:
        try:
            info, secret = create_key(session=session, name=name, role=role.value, robot_ids=robot)
        except ServiceError as exc:
            raise fail(exc) from None
    err_console().print(
        f"created {info.role} key #{info.id} ({info.prefix}) for {info.name!r}; "
        "store it now, it cannot be shown again:"
    )
    typer.echo(secret)


@app.command("list", cls=TidyCommand)
def list_command(
    all_keys: Annotated[bool, typer.Option("--all", help="Include revoked keys.")] = False,
    database_url: DatabaseUrlOption = None,
) -> None:
    """List keys (never their secrets); times are ISO 8601 to the second with their offset."""
    from trajcache.services.catalog.keys import format_time, list_keys

    with open_session(load_settings(database_url)) as session:
        keys = list_keys(session=session, include_revoked=all_keys)
    table = Table(
        *(Column(name, no_wrap=True) for name in ("id", "prefix", "role")),
        *(Column(name, max_width=40, overflow="fold") for name in ("name", "robots")),
        *(Column(name, no_wrap=True) for name in ("created", "revoked")),
    )
    for k in keys:
        table.add_row(
            str(k.id),
            k.prefix,
            k.role,
            k.name,
            ", ".join(k.robot_ids),
            format_time(k.created_at),
            format_time(k.revoked_at) if k.revoked_at else "",
        )
    _print_whole(table)


def _print_whole(table: Table) -> None:
    """Print `table` at its natural width, wider than the terminal if need be: nothing is cut."""
    console = Console()
    natural = console.measure(table, options=console.options.update_width(1_000_000)).maximum
    Console(width=max(console.width, natural)).print(table)


@app.command(cls=TidyCommand)
def revoke(
    key: Annotated[str, typer.Argument(help="Key id or prefix.")],
    database_url: DatabaseUrlOption = None,
) -> None:
    """Revoke a key; services stop accepting it within auth_cache_ttl_s."""
    from trajcache.services.catalog.keys import revoke_key

    with open_session(load_settings(database_url)) as session:
        try:
            info = revoke_key(session=session, key=key)
        except ServiceError as exc:
            raise fail(exc) from None
    err_console().print(f"revoked key #{info.id} ({info.prefix}, {info.name!r})")
