"""`trajcache warm` says how far it got: one line per kernel group with its time when its output
is not a terminal (a log, a container build), a progress bar on a terminal."""

from __future__ import annotations

import io
import os
import re
import subprocess
import sys

from rich.console import Console

from trajcache.cli.warm import warm_kernels
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
