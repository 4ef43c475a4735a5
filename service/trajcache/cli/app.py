"""The `trajcache` command line: one module per command group, assembled here."""

from __future__ import annotations

import typer

import trajcache.cli.demo as demo
import trajcache.cli.docs as docs
import trajcache.cli.keys as keys
import trajcache.cli.reference as reference
import trajcache.cli.robots as robots
import trajcache.cli.seed as seed
import trajcache.cli.serve as serve
import trajcache.cli.transfer as transfer
import trajcache.cli.warm as warm
import trajcache.cli.worker as worker
from trajcache.cli.help import TidyCommand, TidyGroup

app = typer.Typer(
    cls=TidyGroup,
    help="trajcache: a shared, collision-validated trajectory cache.",
    no_args_is_help=True,
)
app.command("serve", cls=TidyCommand)(serve.serve)
app.command("migrate", cls=TidyCommand)(serve.migrate_command)
app.command("warm", cls=TidyCommand)(warm.warm_command)
app.command(
    "worker", cls=TidyCommand, help="Start a Celery planner worker (broker from settings)."
)(worker.worker)
app.add_typer(keys.app, name="keys")
app.command("seed", cls=TidyCommand)(seed.seed)
app.command("export", cls=TidyCommand)(transfer.export_command)
app.command("import", cls=TidyCommand)(transfer.import_command)
app.command("prune", cls=TidyCommand)(transfer.prune_command)
app.add_typer(reference.app, name="reference")
app.add_typer(robots.app, name="robots")
app.command("openapi", cls=TidyCommand)(docs.openapi)
app.command("config-table", cls=TidyCommand)(docs.config_table_command)
app.command("demo", cls=TidyCommand)(demo.demo)
