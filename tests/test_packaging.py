"""The distribution ships the service and the client, each with its `py.typed` marker."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_wheel_holds_both_packages_typed(tmp_path: Path) -> None:
    source = tmp_path / "src"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    for package in ("service", "client"):
        shutil.copytree(
            ROOT / package, source / package, ignore=shutil.ignore_patterns("__pycache__")
        )
    out = tmp_path / "dist"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(source)],
        check=True,
        capture_output=True,
        timeout=600,
    )
    (wheel,) = out.glob("trajcache-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for package in ("trajcache", "trajcache_client"):
        assert f"{package}/__init__.py" in names and f"{package}/py.typed" in names
    assert "trajcache_client/_client.py" in names and "trajcache/api/schemas.py" in names
    entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    assert "trajcache = trajcache.cli:app" in zipfile.ZipFile(wheel).read(entry_points).decode()
