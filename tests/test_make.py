"""The Makefile's two commands: `make serve` installs the package alone, `make test` the
development extras too (read from `make -n`, which prints the commands and runs none)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _commands(target: str, venv: Path) -> list[str]:
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    done = subprocess.run(
        ["make", "-n", "--no-print-directory", "-C", str(ROOT), target, f"VENV={venv}"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return [line.strip() for line in done.stdout.splitlines() if line.strip()]


def test_make_serve_installs_only_the_runtime_package(tmp_path: Path) -> None:
    commands = _commands("serve", tmp_path / "venv")
    installs = [c for c in commands if " install " in c and "--upgrade pip" not in c]
    assert installs == [f"{tmp_path / 'venv'}/bin/pip install --quiet -e ."]
    assert commands[-1] == f"{tmp_path / 'venv'}/bin/trajcache serve"


def test_make_test_installs_the_development_extras(tmp_path: Path) -> None:
    commands = _commands("test", tmp_path / "venv")
    assert any(c.endswith('pip install --quiet -e ".[dev]"') for c in commands)
    assert commands[-1].startswith(f"{tmp_path / 'venv'}/bin/pytest -q")
