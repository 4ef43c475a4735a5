"""The `trajcache` command line; each command group lives in its own `cli_*` module."""

from __future__ import annotations

import typer

from trajcache.cli_reference import app as reference_app

app = typer.Typer(
    help="trajcache: a shared, collision-validated trajectory cache.", no_args_is_help=True
)
app.add_typer(reference_app, name="reference")

if __name__ == "__main__":
    app()
