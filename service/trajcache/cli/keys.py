"""`trajcache keys create|list|revoke`: manage API keys in the database (`--database-url`)."""

from __future__ import annotations

from enum import Enum
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Column, Table

from trajcache.cli.common import DatabaseUrlOption, err_console, fail, load_settings, open_session
from trajcache.cli.help import TidyCommand, TidyGroup


class KeyRole(str, Enum):
    """The roles `keys create --role` takes (those of `services.catalog.keys.Role`, named here
    so that the command line's help needs no database layer)."""

    ROBOT = "robot"
    SEEDER = "seeder"
    ADMIN = "admin"


app = typer.Typer(cls=TidyGroup, help="Create, list and revoke API keys.", no_args_is_help=True)


@app.command(cls=TidyCommand)
def create(
    name: Annotated[str, typer.Option(metavar="NAME", help="Who or what the key is for.")],
    role: Annotated[KeyRole, typer.Option(help="What the key may do.")],
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
    from trajcache.services.errors import ServiceError

    settings = load_settings(database_url)
    with open_session(settings, migrate=True) as session:
        try:
            info, secret = create_key(session=session, name=name, role=role.value, robot_ids=robot)
        except ServiceError as exc:
            raise fail(exc) from None
    console = err_console()
    console.print(
        f"created {info.role} key #{info.id} ({info.prefix}) for {info.name!r}; "
        "store it now, it cannot be shown again:"
    )
    typer.echo(secret)
    console.print(auth_note(settings.auth_mode, active_keys=None), soft_wrap=True)


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
    from trajcache.services.catalog.keys import list_keys, revoke_key
    from trajcache.services.errors import ServiceError

    settings = load_settings(database_url)
    with open_session(settings) as session:
        try:
            info = revoke_key(session=session, key=key)
        except ServiceError as exc:
            raise fail(exc) from None
        active = len(list_keys(session=session))
    console = err_console()
    console.print(f"revoked key #{info.id} ({info.prefix}, {info.name!r})")
    console.print(auth_note(settings.auth_mode, active_keys=active), soft_wrap=True)


def auth_note(mode: str, *, active_keys: int | None) -> str:
    """Whether the service requires keys now (`active_keys`: those left after a revocation,
    None after a creation), and how an operator turns checks off."""
    off = "an operator turns key checks off with TRAJCACHE_AUTH_MODE=off"
    if mode == "off":
        return (
            "key checks are off here (TRAJCACHE_AUTH_MODE=off): a service run with this setting "
            "asks for no key; with auto or on it requires one"
        )
    why = (
        "TRAJCACHE_AUTH_MODE=on"
        if mode == "on"
        else (
            "TRAJCACHE_AUTH_MODE=auto: keys stay required once one was created, even after all "
            "are revoked"
        )
    )
    if active_keys is None:
        return f"the service now requires an API key on every /v1 request ({why}); {off}"
    if active_keys == 0:
        return (
            f"no active key is left, and the service still requires one ({why}): create one "
            f"with `trajcache keys create`, or {off}"
        )
    return f"{active_keys} active key(s) left; the service still requires keys ({why}); {off}"
