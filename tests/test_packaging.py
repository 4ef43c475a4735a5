"""The distribution ships the service and the client, each with its `py.typed` marker.

`trajcache demo` runs from an installed package: its modules are in the wheel, and importing
them needs neither the benchmark harness (`bench/`, not installed) nor matplotlib."""

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
    assert "trajcache_client/_client.py" in names and "trajcache/api/schemas/models.py" in names
    for module in ("cli/__main__", "cli/launch", "cli/demo", "cli/demo_play", "reference/robot"):
        assert f"trajcache/{module}.py" in names, module
    assert not [n for n in names if n.startswith(("trajcache/protocol/", "harness/", "bench/"))]
    for asset in ("swagger-ui/swagger-ui-bundle.js", "swagger-ui/swagger-ui.css", "redoc/LICENSE"):
        assert f"trajcache/api/static/{asset}" in names, asset  # /docs works offline
    assert "trajcache/api/static/NOTICE.md" in names
    entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    assert "trajcache = trajcache.cli:app" in zipfile.ZipFile(wheel).read(entry_points).decode()


def test_the_demo_needs_neither_the_bench_harness_nor_matplotlib(tmp_path: Path) -> None:
    code = (
        "import sys; import trajcache.cli.demo, trajcache.cli.demo_play, trajcache.cli.launch; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('harness', 'matplotlib')))"
    )
    path = [p for p in sys.path if Path(p).resolve() != ROOT / "bench"]
    env = {"PYTHONPATH": ":".join(p for p in path if p)}
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"
