"""The `trajcache` command line; each command group lives in its own `cli_*` module."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console

from trajcache import cli_demo, cli_seed, cli_transfer
from trajcache.cli_keys import app as keys_app
from trajcache.cli_openapi import config_table_command, openapi
from trajcache.cli_reference import app as reference_app
from trajcache.jobs.worker_cli import worker

if TYPE_CHECKING:
    from trajcache.core.config import Settings

app = typer.Typer(
    help="trajcache: a shared, collision-validated trajectory cache.", no_args_is_help=True
)
app.add_typer(reference_app, name="reference")
app.add_typer(keys_app, name="keys")
app.command("worker", help="Start a Celery planner worker (broker from settings).")(worker)
app.command("openapi")(openapi)
app.command("config-table")(config_table_command)
cli_seed.register(app)  # seed
cli_transfer.register(app)  # export, import, prune
cli_demo.register(app)  # demo


def _settings() -> Settings:
    from pydantic import ValidationError

    from trajcache.core.config import Settings

    try:
        return Settings()
    except ValidationError as exc:
        Console(stderr=True).print(f"[red]invalid TRAJCACHE_* settings:[/red] {exc}")
        raise typer.Exit(2) from None


@app.command()
def serve(
    host: Annotated[
        str | None, typer.Option(help="Address to bind (default: TRAJCACHE_HOST).")
    ] = None,
    port: Annotated[
        int | None, typer.Option(min=1, max=65535, help="Port (default: TRAJCACHE_PORT).")
    ] = None,
    workers: Annotated[int, typer.Option(min=1, help="Server worker processes.")] = 1,
    no_migrate: Annotated[
        bool, typer.Option("--no-migrate", help="Do not upgrade the database on start.")
    ] = False,
) -> None:
    """Run the HTTP service (settings from TRAJCACHE_* environment variables)."""
    import uvicorn

    from trajcache.metrics_dir import prepare_multiprocess_dir

    prepare_multiprocess_dir(workers)  # before any metric exists: workers merge /metrics there
    from trajcache.db import migrate
    from trajcache.main import AUTO_MIGRATE_ENV

    settings = _settings()
    host = host or settings.host
    port = port or settings.port
    if not no_migrate:
        migrate.upgrade(settings.database_url)  # once here rather than once per worker
    os.environ[AUTO_MIGRATE_ENV] = "0"
    os.environ["TRAJCACHE_HOST"] = host  # the app decides from it whether keys are required
    shown = f"[{host}]" if ":" in host else host
    Console(stderr=True).print(
        f"trajcache serving on [bold]http://{shown}:{port}[/bold] "
        f"(API docs at /docs, {workers} worker{'s' if workers > 1 else ''})"
    )
    uvicorn.run(
        "trajcache.main:create_app",
        factory=True,
        host=host,
        port=port,
        workers=workers,
        log_level=settings.log_level,
    )


@app.command("migrate")
def migrate_command(
    revision: Annotated[str, typer.Option(help="Target revision.")] = "head",
) -> None:
    """Upgrade the configured database (TRAJCACHE_DATABASE_URL) to a revision."""
    from sqlalchemy.engine import make_url

    from trajcache.db import migrate

    settings = _settings()
    url = settings.database_url
    migrate.upgrade(url, revision)
    shown = make_url(url).render_as_string(hide_password=True)
    Console().print(f"{shown} is at revision [bold]{migrate.current_revision(url)}[/bold]")


if __name__ == "__main__":
    app()
