"""`trajcache warm`: compile the kernels ahead of time, saying how far it got.

The first time on a machine numba compiles every kernel (one to two minutes on 2 cores); after
that it loads them from its on-disk cache in seconds. On a terminal a progress bar names the
group being compiled; otherwise (a log, a pipe, a container build) each group is one line with
its time. `trajcache serve` and `trajcache worker` warm the same way before they start.

A first warm on a machine with two cores or more compiles the longest group (`OFFLOADED`, about
two thirds of the whole) in a second process while this one compiles the others; this process
then loads that group from numba's cache. Whether the cache already holds the group is read from
numba's index files of its largest kernels (`OFFLOAD_PROBES`), their source stamps included (so
an upgrade that changed a kernel counts as a first warm); when it does, nothing is started and
the groups load in order here. Two processes writing numba's cache at once is safe: each entry
is written to a temporary file and renamed.
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from multiprocessing.process import BaseProcess

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from trajcache.cli.common import err_console

Step = tuple[str, Callable[[], None]]
STEPS = "trajcache.planning.warm:warm_steps"  # where the kernel groups are listed
OFFLOADED = "certified validation"
OFFLOAD_PROBES = (
    "trajcache.geometry.collision.compiled.scene_open:scene_open_kernel",
    "trajcache.geometry.collision.compiled.self_open:self_open_kernel",
)
SECOND_PROCESS_NOTE = "compiled in a second process"


def _resolve(path: str) -> object:
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


def _import_steps(steps: str = STEPS) -> list[Step]:
    listed = _resolve(steps)
    assert callable(listed)
    return list(listed())


def kernels_cached(probes: tuple[str, ...]) -> bool:
    """Whether numba's on-disk cache holds a current entry for every kernel named in `probes`
    ("module:function", each compiled with `cache=True`): an index whose source stamp matches
    (an index left by older sources is stale); False for any that cannot tell."""
    for probe in probes:
        try:
            index = _resolve(probe)._cache._cache_file._load_index()  # type: ignore[attr-defined]
        except (AttributeError, ImportError, OSError, EOFError, ValueError):
            return False
        if not index:
            return False
    return True


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _run_group(steps: str, name: str) -> None:
    """In the second process: compile one group."""
    for group, run in _import_steps(steps):
        if group == name:
            run()


def _second_process(steps: str, name: str) -> BaseProcess:
    process = multiprocessing.get_context("spawn").Process(
        target=_run_group, args=(steps, name), name=f"trajcache warm: {name}", daemon=True
    )
    process.start()
    return process


@contextmanager
def _offloading(
    steps: list[Step], source: str, offload: str | None
) -> Iterator[tuple[list[Step], set[str]]]:
    """The groups in the order this process runs them, and those a second process compiles
    (run here last, after it ended, when they load from the cache)."""
    if offload is None or offload not in {name for name, _ in steps}:
        yield steps, set()
        return
    process = _second_process(source, offload)

    def after_second_process() -> None:
        process.join()
        dict(steps)[offload]()  # loads what it compiled (or compiles, had it failed)

    ordered = [step for step in steps if step[0] != offload]
    try:
        yield [*ordered, (offload, after_second_process)], {offload}
    finally:
        if process.is_alive():
            process.terminate()


def _offload_choice(offload: str | None, probes: tuple[str, ...]) -> str | None:
    if offload is not None:
        return offload
    return OFFLOADED if _cores() >= 2 and not kernels_cached(probes) else None


def _timed(run: Callable[[], object]) -> float:
    began = time.perf_counter()
    run()
    return time.perf_counter() - began


def _warm_with_bar(console: Console, steps: str, offload: str | None) -> float:
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn())
    with Progress(*columns, TimeElapsedColumn(), console=console, transient=True) as progress:
        task = progress.add_task("loading the geometry modules", total=None)
        began = time.perf_counter()
        listed = _import_steps(steps)
        progress.update(task, total=len(listed))
        with _offloading(listed, steps, _offload_choice(offload, OFFLOAD_PROBES)) as (
            ordered,
            beside,
        ):
            for name, run in ordered:
                progress.update(task, description=f"compiling kernels: {name}")
                seconds = _timed(run)
                note = f" ({SECOND_PROCESS_NOTE})" if name in beside else ""
                progress.console.print(f"  {name}: {seconds:.1f} s{note}")
                progress.advance(task)
        return time.perf_counter() - began


def _warm_with_lines(console: Console, steps: str, offload: str | None) -> float:
    began = time.perf_counter()
    listed = _import_steps(steps)
    seconds = time.perf_counter() - began
    console.print(f"kernels: geometry modules loaded in {seconds:.1f} s", soft_wrap=True)
    chosen = _offload_choice(offload, OFFLOAD_PROBES)
    with _offloading(listed, steps, chosen) as (ordered, beside):
        if beside:
            console.print(f"kernels: {chosen} {SECOND_PROCESS_NOTE}", soft_wrap=True)
        for i, (name, run) in enumerate(ordered, start=1):
            seconds = _timed(run)
            note = f" ({SECOND_PROCESS_NOTE})" if name in beside else ""
            line = f"kernels {i}/{len(ordered)}: {name} in {seconds:.1f} s{note}"
            console.print(line, soft_wrap=True)
    return time.perf_counter() - began


def warm_kernels(
    console: Console | None = None, *, steps: str = STEPS, offload: str | None = None
) -> None:
    """Compile (or load from numba's cache) every kernel group, with a progress bar on a
    terminal and one line per group otherwise, then one line with the total. `offload` names a
    group for a second process (default: `OFFLOADED` on a first warm with two cores or more)."""
    console = console or err_console()
    warm_fn = _warm_with_bar if console.is_terminal else _warm_with_lines
    total = warm_fn(console, steps, offload)
    console.print(f"kernels ready in {total:.1f} s", soft_wrap=True)


def warm_command() -> None:
    """Compile the kernels now (numba keeps them on disk), so that no start waits for them."""
    warm_kernels()
