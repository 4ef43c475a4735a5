"""`trajcache export`, `trajcache import`, `trajcache prune`: the cache in the database, directly.

These work on the database of TRAJCACHE_DATABASE_URL (or `--database-url`), with or without a
running service: running replicas pick up imported trajectories at their next sync, and drop
pruned ones the same way (prune leaves tombstones). The JSON Lines format is documented in
`trajcache.services.maintenance.transfer`; a gzip-compressed file is unpacked (whatever its
name). An import is one transaction: a corrupt, truncated or empty file imports nothing.
"""

from __future__ import annotations

import gzip
import os
import re
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime, timedelta
from enum import Enum
from pathlib import Path
from typing import IO, TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    DownloadColumn,
    MofNCompleteColumn,
    Progress,
    TimeElapsedColumn,
)
from rich.table import Table

from trajcache.cli.common import DatabaseUrlOption, err_console, fail, load_settings, open_session

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from trajcache.services.maintenance.importer import ImportReport

_DURATION = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([smhdw]?)\s*$")
_UNITS = {"": 1, "s": 1, "m": 60, "h": 3600, "d": 86400, "w": 604800}


class EvictionPolicy(str, Enum):
    """The eviction policies `trajcache prune --policy` takes (those of eviction.POLICIES)."""

    LRU = "lru"
    LEAST_HIT = "least_hit"


def parse_duration(text: str, option: str) -> timedelta:
    """`90`, `90s`, `15m`, `12h`, `7d` or `2w` as a timedelta."""
    match = _DURATION.match(text)
    if match is None:
        raise typer.BadParameter(
            f"{text!r} is not a duration (e.g. 90s, 15m, 12h, 7d)", param_hint=option
        )
    return timedelta(seconds=float(match.group(1)) * _UNITS[match.group(2)])


def _progress(console: Console, *, in_bytes: bool = False) -> Progress:
    return Progress(
        "[progress.description]{task.description}",
        BarColumn(),
        DownloadColumn() if in_bytes else MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
    )


@contextmanager
def _output(out: Path | None) -> Iterator[IO[str]]:
    if out is None or str(out) == "-":
        yield sys.stdout
    elif out.suffix == ".gz":
        with gzip.open(out, "wt", encoding="utf-8") as handle:
            yield handle
    else:
        with out.open("w", encoding="utf-8") as handle:
            yield handle


def export_command(
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", help="File to write (`.gz`: gzip); default stdout."),
    ] = None,
    model: Annotated[
        list[str] | None,
        typer.Option("--model", metavar="MODEL_ID", help="Only this model (repeat)."),
    ] = None,
    source: Annotated[
        list[str] | None,
        typer.Option("--source", metavar="SOURCE", help="Only this source (repeat)."),
    ] = None,
    newer_than: Annotated[
        str | None,
        typer.Option(
            metavar="DURATION", help="Only trajectories stored within this long (e.g. 7d)."
        ),
    ] = None,
    older_than: Annotated[
        str | None,
        typer.Option(metavar="DURATION", help="Only trajectories stored longer ago than this."),
    ] = None,
    models: Annotated[bool, typer.Option(help="Include model lines (URDF and files).")] = True,
    database_url: DatabaseUrlOption = None,
) -> None:
    """Export cached trajectories (and their models) as JSON Lines."""
    from trajcache.services.errors import ServiceError
    from trajcache.services.maintenance.transfer import (
        ExportFilter,
        count_exported,
        dumps,
        export_records,
    )

    now = datetime.now(UTC)
    newer = None if newer_than is None else now - parse_duration(newer_than, "--newer-than")
    older = None if older_than is None else now - parse_duration(older_than, "--older-than")
    filt = ExportFilter(
        model_ids=tuple(model or ()),
        sources=tuple(source or ()),
        created_after=newer,
        created_before=older,
    )
    console = err_console()
    written = 0
    with open_session(load_settings(database_url)) as session, _output(out) as handle:
        try:
            total = count_exported(session, filt)
            with _progress(console) as bar:
                task = bar.add_task("exporting", total=total)
                for record in export_records(session=session, filt=filt, include_models=models):
                    handle.write(dumps(record) + "\n")
                    if record["type"] == "trajectory":
                        written += 1
                        bar.advance(task)
        except ServiceError as exc:
            raise fail(exc) from None
    console.print(f"exported {written} trajectories" + (f" to {out}" if out else ""))


@contextmanager
def _input(path: Path, bar: Progress) -> Iterator[Iterator[str]]:
    from trajcache.services.maintenance.reading import CHUNK_BYTES, export_lines

    with bar.open(path, "rb", description=f"importing {path.name}") as raw:
        chunks = iter(lambda: raw.read(CHUNK_BYTES), b"")
        yield export_lines(chunks=chunks, what="file")


IMPORT_NICENESS = 10


def lower_priority(niceness: int) -> None:
    """Add `niceness` to this process's CPU niceness (where the platform has one): a bulk
    import yields the CPU to the service answering robots on the same machine."""
    if niceness > 0 and hasattr(os, "nice"):
        os.nice(niceness)


_LOCAL_HOSTS = frozenset({None, "", "localhost", "127.0.0.1", "::1"})


def lower_database_priority(session: Session, niceness: int) -> bool:
    """Add `niceness` to the session's PostgreSQL backend too, where the server runs on this
    machine and this user may renice it; whether it did. The backend does the import's COPY
    and index work, as much CPU as the import itself: without it, a niced import still takes a
    core from the backends answering robots. A backend pid of another pid namespace (a
    database in a container) names no postgres process here and is left alone."""
    bind = session.get_bind()
    if niceness <= 0 or not hasattr(os, "setpriority") or bind.dialect.name != "postgresql":
        return False
    if bind.engine.url.host not in _LOCAL_HOSTS:
        return False
    import sqlalchemy as sa  # here: `--help` loads no database layer

    pid = int(session.execute(sa.text("SELECT pg_backend_pid()")).scalar_one())
    try:
        if Path(f"/proc/{pid}/comm").read_text().strip() != "postgres":
            return False
        now = os.getpriority(os.PRIO_PROCESS, pid)
        os.setpriority(os.PRIO_PROCESS, pid, min(19, now + niceness))
    except OSError:  # not ours to renice, or gone
        return False
    return True


def import_command(
    file: Annotated[Path, typer.Argument(help="JSON Lines export, or gzip of it.", exists=True)],
    source: Annotated[
        str | None,
        typer.Option(
            metavar="SOURCE", help="Store every trajectory with this source (e.g. import)."
        ),
    ] = None,
    show_rejected: Annotated[int, typer.Option(min=0, help="Rejected lines to list.")] = 20,
    migrate: Annotated[bool, typer.Option(help="Upgrade the database schema first.")] = True,
    nice: Annotated[
        int,
        typer.Option(
            min=0,
            max=19,
            envvar="TRAJCACHE_IMPORT_NICENESS",
            help="CPU niceness added to the import, so a service on the same "
            "machine keeps answering first (0: none).",
        ),
    ] = IMPORT_NICENESS,
    database_url: DatabaseUrlOption = None,
) -> None:
    """Import an export in one transaction; idempotent. Exit status 1: lines were rejected.

    Trajectories are written in batches; their quality is computed afterwards by a running
    service, in the background (they show `quality_pending` until then)."""
    from trajcache.services.catalog.models import ModelRegistry
    from trajcache.services.errors import ServiceError
    from trajcache.services.maintenance.importer import import_lines

    settings = load_settings(database_url)
    console = err_console()
    lower_priority(nice)
    try:
        with (
            open_session(settings, migrate=migrate) as session,
            _progress(console, in_bytes=True) as bar,
            _input(file, bar) as lines,
        ):
            lower_database_priority(session, nice)
            report = import_lines(
                session=session,
                registry=ModelRegistry(),
                settings=settings,
                lines=lines,
                source=source,
            )
    except (ServiceError, OSError) as exc:
        raise fail(exc) from None
    _print_report(report, file.name, show_rejected, console)


def _print_report(report: ImportReport, name: str, show_rejected: int, console: Console) -> None:
    """The import's table and its first rejected lines; exit status 1 if lines were rejected."""
    table = Table(title=f"import of {name}", show_header=False)
    table.add_row("lines", str(report.lines))
    table.add_row(
        "models registered / already there", f"{report.models_created} / {report.models_existing}"
    )
    table.add_row("trajectories imported", str(report.inserted))
    table.add_row("already there (skipped)", str(report.duplicates))
    table.add_row(
        "Cartesian paths imported / already there",
        f"{report.cartesian_inserted} / {report.cartesian_duplicates}",
    )
    table.add_row("rejected", str(report.rejected_count))
    Console().print(table)
    for rejected in report.rejected[:show_rejected]:
        console.print(f"line {rejected.line}: {rejected.reason}")
    if report.rejected_count > show_rejected:
        console.print(f"… and {report.rejected_count - show_rejected} more rejected lines")
    if report.rejected_count:
        raise typer.Exit(1)


def prune_command(
    cap: Annotated[
        int | None, typer.Option(min=1, help="Trajectories kept per model (default: setting).")
    ] = None,
    policy: Annotated[
        EvictionPolicy | None,
        typer.Option(help="Which trajectories go first (default: TRAJCACHE_EVICTION_POLICY)."),
    ] = None,
    model: Annotated[
        str | None, typer.Option("--model", metavar="MODEL_ID", help="Only this model.")
    ] = None,
    apply: Annotated[
        bool, typer.Option("--apply", help="Delete (default: dry run, only list).")
    ] = False,
    database_url: DatabaseUrlOption = None,
) -> None:
    """Evict trajectories beyond the per-model cap (a dry run unless --apply)."""
    from trajcache.services.errors import ServiceError
    from trajcache.services.maintenance.eviction import prune

    settings = load_settings(database_url)
    chosen_cap = cap or settings.cache_max_per_model
    if chosen_cap < 1:
        raise typer.BadParameter("no cap: pass --cap, or set TRAJCACHE_CACHE_MAX_PER_MODEL")
    chosen_policy = policy.value if policy is not None else settings.eviction_policy
    with open_session(settings) as session:
        try:
            report = prune(
                session=session,
                cap=chosen_cap,
                policy=chosen_policy,
                model_id=model,
                dry_run=not apply,
            )
        except ServiceError as exc:
            raise fail(exc) from None
    verb = "deleted" if apply else "would delete"
    table = Table(title=f"prune to {chosen_cap} per model ({chosen_policy})")
    table.add_column("model")
    table.add_column("trajectories", justify="right")
    table.add_column(verb, justify="right")
    for m in report.models:
        table.add_row(m.model_id[:16], str(m.trajectories), str(len(m.ids)))
    console = Console()
    console.print(table)
    console.print(
        f"{verb} {report.deleted} trajectories" + ("" if apply else " (dry run: --apply deletes)")
    )
