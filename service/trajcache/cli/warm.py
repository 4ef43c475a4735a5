"""`trajcache warm`: compile the kernels ahead of time, saying how far it got.

The first time on a machine numba compiles every kernel (about a minute); after that it loads
them from its on-disk cache in seconds. On a terminal a progress bar names the group being
compiled; otherwise (a log, a pipe, a container build) each group is one line with its time.
`trajcache serve` warms the same way before it starts the server.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from trajcache.cli.common import err_console

Step = tuple[str, Callable[[], None]]


def _import_steps() -> list[Step]:
    from trajcache.planning.warm import warm_steps

    return warm_steps()


def _timed(run: Callable[[], object]) -> float:
    began = time.perf_counter()
    run()
    return time.perf_counter() - began


def _warm_with_bar(console: Console) -> float:
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn())
    with Progress(*columns, TimeElapsedColumn(), console=console, transient=True) as progress:
        task = progress.add_task("loading the geometry modules", total=None)
        began = time.perf_counter()
        steps = _import_steps()
        progress.update(task, total=len(steps))
        for name, run in steps:
            progress.update(task, description=f"compiling kernels: {name}")
            seconds = _timed(run)
            progress.console.print(f"  {name}: {seconds:.1f} s")
            progress.advance(task)
        return time.perf_counter() - began


def _warm_with_lines(console: Console) -> float:
    began = time.perf_counter()
    steps = _import_steps()
    seconds = time.perf_counter() - began
    console.print(f"kernels: geometry modules loaded in {seconds:.1f} s", soft_wrap=True)
    for i, (name, run) in enumerate(steps, start=1):
        seconds = _timed(run)
        console.print(f"kernels {i}/{len(steps)}: {name} in {seconds:.1f} s", soft_wrap=True)
    return time.perf_counter() - began


def warm_kernels(console: Console | None = None) -> None:
    """Compile (or load from numba's cache) every kernel group, with a progress bar on a
    terminal and one line per group otherwise, then one line with the total."""
    console = console or err_console()
    warm_fn = _warm_with_bar if console.is_terminal else _warm_with_lines
    total = warm_fn(console)
    console.print(f"kernels ready in {total:.1f} s", soft_wrap=True)


def warm_command() -> None:
    """Compile the kernels now (numba keeps them on disk), so that no start waits for them."""
    warm_kernels()
