"""The command line starts light: `--help` and the commands that touch no geometry load neither
the compiled kernels (numba), the collision and planning libraries, nor the database layer.

Each case runs in a fresh interpreter (the test session has imported everything already) and
reads `sys.modules` after the command ran; what is checked is what was imported, not the time.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

HEAVY = ("numba", "pinocchio", "coal", "fcl", "ompl", "sqlalchemy", "trajcache.db")

_PROBE = """
import json, sys
from trajcache.cli import app
try:
    app(sys.argv[1:])
except SystemExit as exc:
    code = exc.code
heavy = {heavy!r}
loaded = sorted(m for m in sys.modules if any(m == h or m.startswith(h + ".") for h in heavy))
print(json.dumps({{"code": code, "loaded": loaded}}))
"""


def _run(*args: str) -> tuple[int, list[str]]:
    """The exit status of `trajcache ARGS` and the heavy modules it imported."""
    done = subprocess.run(
        [sys.executable, "-c", _PROBE.format(heavy=HEAVY), *args],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout.strip().splitlines()[-1])
    return int(report["code"] or 0), list(report["loaded"])


def test_the_probe_sees_a_heavy_import() -> None:
    """A command that does touch geometry is seen loading its libraries (the probe can fail)."""
    code, loaded = _run("reference", "robot", "--out", "/dev/null")
    assert code == 0
    assert {"coal", "fcl"} <= set(loaded)


@pytest.mark.parametrize(
    "args",
    [
        ("--help",),
        ("serve", "--help"),
        ("warm", "--help"),
        ("keys", "create", "--help"),
        ("robots", "fetch", "--help"),
        ("seed", "--help"),
        ("demo", "--help"),
        ("prune", "--help"),
        ("config-table", "--help"),
    ],
    ids=" ".join,
)
def test_help_imports_no_heavy_module(args: tuple[str, ...]) -> None:
    code, loaded = _run(*args)
    assert code == 0
    assert loaded == []


def test_the_settings_table_imports_no_heavy_module() -> None:
    """`config-table` reads the settings (`core.config`), which import no other layer."""
    code, loaded = _run("config-table")
    assert code == 0
    assert loaded == []
