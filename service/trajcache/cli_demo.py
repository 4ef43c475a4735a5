"""`trajcache demo`: a short run of the paper-table protocol on temporary SQLite services."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

if TYPE_CHECKING:
    from trajcache.protocol.paper import RowSpec
    from trajcache.protocol.tables import Row

BEYOND_PAPER = frozenset({"run1_arm", "run2_arm", "real_empty_arm"})


def _doors(text: str) -> tuple[int, ...]:
    """Door angles from "0,45,90"; each within 0…90°."""
    try:
        angles = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise typer.BadParameter(f"door angles must be integers, got {text!r}") from None
    if not angles or any(not 0 <= a <= 90 for a in angles):
        raise typer.BadParameter(f"door angles must lie in 0…90°, got {text!r}")
    return angles


def demo(
    calls: Annotated[
        int | None,
        typer.Option(min=5, help="Play only the first N calls of each run (default: all, ~271)."),
    ] = None,
    seed: Annotated[int, typer.Option(help="Workload seed of run 1.")] = 1,
    doors: Annotated[
        str, typer.Option(help="Door angles (°) of the pre-seeding sweep, comma-separated.")
    ] = "0,45,90",
    arm: Annotated[
        bool,
        typer.Option("--arm/--no-arm", help="Also play the match=arm rows (beyond the paper)."),
    ] = True,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Also write every row as JSON here.")
    ] = None,
    chart: Annotated[
        Path | None, typer.Option(help="Also draw a PNG chart here (needs matplotlib).")
    ] = None,
) -> None:
    """Play a short version of the paper's protocol and print Tables 1 and 2.

    Starts its own services (uvicorn on loopback, one temporary SQLite database per cache),
    plays the reference cleaning workload through the REST API, checks every returned
    trajectory with an independent dense check, and prints the tables with the paper's figures.
    """
    from trajcache.protocol.paper import Protocol, report, row_specs, run_protocol

    console = Console(stderr=True)
    if chart is not None and importlib.util.find_spec("matplotlib") is None:
        raise typer.BadParameter("--chart needs matplotlib (pip install matplotlib)")
    sweep = _doors(doors)
    keys = {s.key for s in row_specs(seed, sweep)}
    protocol = Protocol(
        seed=seed,
        calls=calls,
        sweep=sweep,
        rows=frozenset(keys if arm else keys - BEYOND_PAPER),
        paired=False,
    )
    specs = protocol.specs()
    console.print(
        f"Playing {len(specs)} rows of {calls or 'all'} calls each (seed {seed}, doors "
        f"{', '.join(f'{d}°' for d in sweep)}); starting the services…"
    )
    columns = (TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/"
               "{task.total} rows"), TimeElapsedColumn())  # fmt: skip
    with Progress(*columns, console=console) as progress:
        task = progress.add_task(specs[0].label, total=len(specs))

        def on_row(spec: RowSpec, row: Row, elapsed: float) -> None:
            f = row.figures()
            progress.console.print(
                f"  {spec.label}: {f['hits']}/{f['calls']} hits, {f['planner_calls']} planned, "
                f"{f['collisions']} collisions ({elapsed:.1f} s)"
            )
            done = int(progress.tasks[task].completed) + 1
            label = specs[done].label if done < len(specs) else "done"
            progress.update(task, advance=1, description=label)

        rows, config = run_protocol(protocol, on_row)
    summary = report(rows, config, json_path, chart)
    if summary["collisions"] or summary.get("arm_collisions"):
        console.print("[red]the dense check found returned trajectories in collision[/red]")
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add the `demo` command to the CLI."""
    app.command("demo")(demo)
