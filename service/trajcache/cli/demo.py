"""`trajcache demo`: a short run of the paper's protocol on temporary SQLite services.

It needs nothing but the installed package: the services are started by `trajcache.cli.launch`
and the rows are played by `trajcache.cli.demo_play` with the client library. The full protocol
(paired baseline, PostgreSQL, the independent FCL dense check, the paper's figures, the chart)
is the benchmark harness in `bench/`: `python bench/paper_tables.py` from a checkout.
"""

from __future__ import annotations

import json
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

from trajcache.cli.common import err_console

if TYPE_CHECKING:
    from trajcache.cli.demo_play import RowResult

CACHES = ("none", "sim", "sim_arm", "seeded", "real", "real_arm")
TITLES = {1: "Table 1: simulation", 2: "Table 2: pre-seeding and the real robot"}


def _doors(text: str) -> tuple[int, ...]:
    """Door angles from "0,45,90"; each within 0…90°."""
    try:
        angles = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise typer.BadParameter(f"door angles must be integers, got {text!r}") from None
    if not angles or any(not 0 <= a <= 90 for a in angles):
        raise typer.BadParameter(f"door angles must lie in 0…90°, got {text!r}")
    return angles


def _speedup(result: RowResult, results: dict[str, RowResult]) -> float | None:
    base = results.get(result.row.baseline)
    if base is None or result.service_ms <= 0 or result.row.cache == "none":
        return None
    return round(base.service_ms / result.service_ms, 3)


def row_json(result: RowResult, results: dict[str, RowResult]) -> dict[str, object]:
    """One row as JSON."""
    r = result
    return {"key": r.row.key, "table": r.row.table, "label": r.row.label, "calls": r.calls,
            "hits": r.hits, "planned": r.planned, "failed": r.failed, "checked": r.checked,
            "collisions": r.collisions, "service_s": round(r.service_ms / 1e3, 3),
            "speedup": _speedup(r, results), "messages": r.messages[:5]}  # fmt: skip


def print_tables(results: dict[str, RowResult], scope: str) -> None:
    """Print Tables 1 and 2 (rows marked + are beyond the paper)."""
    head = f"{'row':<38} {'calls':>5} {'hits':>12} {'planned':>7} {'service s':>9} {'speed-up':>8}"
    for table, title in TITLES.items():
        print(f"{title} ({scope})")
        print(head)
        for r in (r for r in results.values() if r.row.table == table):
            hits = "–" if r.row.cache == "none" else f"{r.hits} = {r.hits / max(r.calls, 1):.1%}"
            speedup = _speedup(r, results)
            shown = "–" if speedup is None else f"{speedup:.2f}×"
            print(f"{r.row.label:<38} {r.calls:>5} {hits:>12} {r.planned:>7} "
                  f"{r.service_ms / 1e3:>9.3f} {shown:>8}")  # fmt: skip
        print()


def summary(results: dict[str, RowResult]) -> dict[str, object]:
    """The headline figures: hit rates and speed-ups of run 2 and the seeded real robot."""
    out: dict[str, object] = {}
    for key in ("run1", "run2", "real_seeded", "real_second"):
        r = results.get(key)
        out[f"{key}_hit_rate"] = None if r is None else round(r.hits / max(r.calls, 1), 4)
        out[f"{key}_speedup"] = None if r is None else _speedup(r, results)
    rows = results.values()
    out["collisions"] = sum(r.collisions for r in rows if not r.row.label.startswith("+ "))
    out["arm_collisions"] = sum(r.collisions for r in rows if r.row.label.startswith("+ "))
    out["failed_calls"] = sum(r.failed for r in rows)
    out["trajectories_checked"] = sum(r.checked for r in rows)
    return out


def start_services(stack: ExitStack, names: list[str], console: Console) -> list[str]:
    """Start one service per cache name (closed with `stack`), a line for each one ready."""
    from trajcache.cli.launch import running_services

    env = {"TRAJCACHE_WORKER_PROCESSES": "1"}
    columns = (SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
               TextColumn("{task.completed}/{task.total} ready"), TimeElapsedColumn())  # fmt: skip
    with Progress(*columns, console=console) as progress:
        task = progress.add_task("starting the services", total=len(names))

        def ready(index: int, base: str) -> None:
            progress.console.print(f"  service for the {names[index]!r} cache ready at {base}")
            progress.advance(task)

        services = running_services(
            [None] * len(names), env=env, deadline_s=300, quiet=True, ready_fn=ready
        )
        return stack.enter_context(services)


def play(
    *, seed: int, sweep: tuple[int, ...], arm: bool, calls: int | None
) -> dict[str, RowResult]:
    """Start one service per cache, play every row with a progress bar; the rows' results."""
    from trajcache.cli.demo_play import Checker, demo_rows, play_row, prepare
    from trajcache_client import Client

    console = err_console()
    rows = demo_rows(seed=seed, doors=sweep, arm=arm)
    names = [name for name in CACHES if any(r.cache == name for r in rows)]
    shown = ", ".join(f"{d}°" for d in sweep)
    console.print(
        f"Playing {len(rows)} rows of {calls or 'all'} calls each (seed {seed}, doors {shown}) "
        f"on {len(names)} services"
    )
    columns = (TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/"
               "{task.total} rows"), TimeElapsedColumn())  # fmt: skip
    results: dict[str, RowResult] = {}
    with ExitStack() as stack:
        bases = start_services(stack, names, console)
        clients = {n: Client(b, timeout=120) for n, b in zip(names, bases, strict=True)}
        models = {n: prepare(c) for n, c in clients.items()}
        checker = Checker()
        with Progress(*columns, console=console) as progress:
            task = progress.add_task(rows[0].label, total=len(rows))
            for i, row in enumerate(rows):
                progress.update(task, description=row.label)
                r = play_row(clients[row.cache], models[row.cache], row, calls, checker)
                progress.console.print(f"  {row.label}: {r.hits}/{r.calls} hits, {r.planned} "
                                       f"planned, {r.collisions} collisions")  # fmt: skip
                results[row.key] = r
                progress.update(task, completed=i + 1)
        for client in clients.values():
            client.close()
    return results


def demo(
    calls: Annotated[
        int | None,
        typer.Option(min=5, help="Play only the first N calls of each run (default: all, ~271)."),
    ] = None,
    seed: Annotated[int, typer.Option(help="Workload seed of run 1.")] = 1,
    doors: Annotated[
        str,
        typer.Option(
            metavar="DEGREES", help="Door angles (°) of the pre-seeding sweep, comma-separated."
        ),
    ] = "0,45,90",
    arm: Annotated[
        bool,
        typer.Option("--arm/--no-arm", help="Also play the match=arm rows (beyond the paper)."),
    ] = True,
    json_path: Annotated[
        Path | None,
        typer.Option("--json", metavar="PATH", help="Also write every row as JSON here."),
    ] = None,
) -> None:
    """Play a short version of the paper's protocol and print Tables 1 and 2.

    Needs only the installed package: starts its own services (uvicorn on loopback, one
    temporary SQLite database per cache), plays the reference cleaning workload through the REST
    API, re-checks every returned trajectory with the package's validator 4× finer than the
    service, prints both tables and a JSON line, and exits 1 if a trajectory collides. The full
    protocol with the paper's figures, an independent FCL check and a chart is
    `python bench/paper_tables.py` in a source checkout.
    """
    sweep = _doors(doors)
    results = play(seed=seed, sweep=sweep, arm=arm, calls=calls)
    print_tables(results, f"{calls or 'all'} calls per run, seed {seed}, sqlite")
    figures = summary(results)
    if json_path is not None:
        config = {"seed": seed, "calls_per_run": calls, "sweep_deg": list(sweep)}
        rows = [row_json(r, results) for r in results.values()]
        document = {"config": config, "rows": rows, "summary": figures}
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(document, indent=1), encoding="utf-8")
    print(json.dumps(figures))
    if figures["collisions"] or figures["arm_collisions"]:
        err_console().print("[red]the re-check found returned trajectories in collision[/red]")
        raise typer.Exit(1)
