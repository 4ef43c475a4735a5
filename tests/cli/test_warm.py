"""`trajcache warm` says how far it got: one line per kernel group with its time when its output
is not a terminal (a log, a container build), a progress bar on a terminal."""

from __future__ import annotations

import importlib
import io
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from rich.console import Console

from trajcache.cli.warm import (
    OFFLOADED,
    SECOND_PROCESS_NOTE,
    _cores,
    _offload_choice,
    kernels_cached,
    warm_kernels,
)
from trajcache.planning.warm import warm_steps

GROUPS = [name for name, _ in warm_steps()]
_FORCING = ("FORCE_COLOR", "TTY_COMPATIBLE", "TTY_INTERACTIVE")  # would make rich draw a bar


def test_every_kernel_group_is_named() -> None:
    assert GROUPS == [
        "distance bounds",
        "certified validation",
        "collision checks",
        "sphere checks",
        "compiled planner",
    ]


def test_warm_writes_one_line_per_group_with_its_time_when_not_on_a_terminal() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "trajcache.cli", "warm"],
        capture_output=True,
        text=True,
        timeout=600,
        env={k: v for k, v in os.environ.items() if k not in _FORCING} | {"TERM": "dumb"},
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert re.fullmatch(r"kernels: geometry modules loaded in \d+\.\d s", lines[0]), lines
    count = len(GROUPS)
    expected = [
        rf"kernels {i}/{count}: {re.escape(name)} in \d+\.\d s"
        for i, name in enumerate(GROUPS, start=1)
    ]
    assert len(lines) == count + 2, lines
    for pattern, line in zip(expected, lines[1:-1], strict=True):
        assert re.fullmatch(pattern, line), line
    assert re.fullmatch(r"kernels ready in \d+\.\d s", lines[-1]), lines
    assert "\x1b" not in done.stderr  # no bar, no colour codes in a log


def test_warm_draws_a_bar_on_a_terminal() -> None:
    out = io.StringIO()
    console = Console(file=out, force_terminal=True, width=100)
    warm_kernels(console)
    drawn = out.getvalue()
    assert "\x1b[" in drawn  # drawn, not logged
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", drawn)
    assert "compiling kernels" in text
    for name in GROUPS:
        assert re.search(rf"{re.escape(name)}: \d+\.\d s", text), text
    assert re.search(r"kernels ready in \d+\.\d s", text)


_KERNEL = "import numba\n\n\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n"
_TOY_STEPS = """import os


def _record(name):
    def run():
        with open(os.environ["TRAJCACHE_WARM_TOY"], "a") as out:
            out.write(f"{name} {os.getpid()}\\n")

    return run


def steps():
    return [(name, _record(name)) for name in ("first", "long", "last")]
"""


def test_kernels_cached_reads_numba_index_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "warm_probe_kernel.py").write_text(_KERNEL)
    monkeypatch.syspath_prepend(str(tmp_path))
    import warm_probe_kernel

    probe = ("warm_probe_kernel:twice",)
    assert not kernels_cached(probe)  # never compiled: numba has no index for it
    assert not kernels_cached(("warm_probe_kernel:no_such_kernel",))
    assert _offload_choice(None, probe) == (OFFLOADED if _cores() >= 2 else None)
    assert warm_probe_kernel.twice(3) == 6
    assert kernels_cached(probe)
    assert _offload_choice(None, probe) is None  # a warm cache: nothing is started
    source = tmp_path / "warm_probe_kernel.py"
    source.write_text(_KERNEL.replace("2 * x", "3 * x"))
    os.utime(source, ns=(source.stat().st_mtime_ns + 10**9,) * 2)
    importlib.reload(warm_probe_kernel)
    assert not kernels_cached(probe)  # its index is there, but stamped with the old source


def test_an_offloaded_group_is_compiled_in_a_second_process_then_loaded_here(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "warm_toy_steps.py").write_text(_TOY_STEPS)
    monkeypatch.syspath_prepend(str(tmp_path))
    record = tmp_path / "runs.txt"
    monkeypatch.setenv("TRAJCACHE_WARM_TOY", str(record))
    out = io.StringIO()
    warm_kernels(Console(file=out, width=200), steps="warm_toy_steps:steps", offload="long")
    runs = [line.split() for line in record.read_text().splitlines()]
    here = str(os.getpid())
    assert [name for name, pid in runs if pid == here] == ["first", "last", "long"]
    assert [name for name, pid in runs if pid != here] == ["long"]  # the second process's
    lines = out.getvalue().splitlines()
    assert lines[1] == f"kernels: long {SECOND_PROCESS_NOTE}"
    assert re.fullmatch(rf"kernels 3/3: long in \d+\.\d s \({SECOND_PROCESS_NOTE}\)", lines[4])
