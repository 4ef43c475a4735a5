"""The distribution ships the service and the client, each with its `py.typed` marker, and the
database migrations: a plain (not editable) install migrates a database away from any checkout.

`trajcache demo` runs from an installed package: its modules are in the wheel, and importing
them needs neither the benchmark harness (`bench/`, not installed) nor matplotlib."""

from __future__ import annotations

import shutil
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest
import sqlalchemy as sa

from trajcache.db.migrate import current_revision

ROOT = Path(__file__).resolve().parents[1]
MIGRATIONS = sorted(
    p.relative_to(ROOT / "service").as_posix()
    for p in (ROOT / "service" / "trajcache" / "db" / "migrations").rglob("*")
    if p.is_file() and "__pycache__" not in p.parts
)


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The wheel, built from a copy of the sources that is gone once it is built."""
    tmp = tmp_path_factory.mktemp("wheel")
    source = tmp / "src"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    for package in ("service", "client"):
        shutil.copytree(
            ROOT / package, source / package, ignore=shutil.ignore_patterns("__pycache__")
        )
    out = tmp / "dist"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(source)],
        check=True,
        capture_output=True,
        timeout=600,
    )
    shutil.rmtree(source)
    (built,) = out.glob("trajcache-*.whl")
    return built


@pytest.mark.slow
def test_the_wheel_holds_both_packages_typed(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    for package in ("trajcache", "trajcache_client"):
        assert f"{package}/__init__.py" in names and f"{package}/py.typed" in names
    assert "trajcache_client/_client.py" in names and "trajcache/api/schemas/models.py" in names
    for module in ("cli/__main__", "cli/launch", "cli/demo", "cli/demo_play", "reference/robot"):
        assert f"trajcache/{module}.py" in names, module
    vendored = "trajcache/dashboard/static/vendor/three/"
    for name in ("three.module.js", "three.core.js", "LICENSE", "addons/loaders/STLLoader.js"):
        assert vendored + name in names, name  # the 3D view works from an installed package
    assert not [n for n in names if n.startswith(("trajcache/protocol/", "harness/", "bench/"))]
    for asset in ("swagger-ui/swagger-ui-bundle.js", "swagger-ui/swagger-ui.css", "redoc/LICENSE"):
        assert f"trajcache/api/static/{asset}" in names, asset  # /docs works offline
    assert "trajcache/api/static/NOTICE.md" in names
    assert len(MIGRATIONS) > 3 and set(MIGRATIONS) <= names
    entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    assert "trajcache = trajcache.cli:app" in zipfile.ZipFile(wheel).read(entry_points).decode()


def _isolated_install(wheel: Path, where: Path) -> Path:
    """A fresh virtual environment holding the wheel (no dependencies), which borrows this
    one's installed dependencies by a `.pth` of its site directories: their `.pth` files, the
    editable install's finder among them, are not run there. Its `bin/`."""
    venv.create(where, with_pip=False)
    python = where / "bin" / "python"
    subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(python), "install", "-q", "--no-deps",
         "--no-index", str(wheel)],
        check=True, capture_output=True, timeout=300,
    )  # fmt: skip
    site = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True, capture_output=True, text=True,
    ).stdout.strip()  # fmt: skip
    ours = [p for p in sys.path if Path(p).is_dir() and p.startswith(sys.prefix)]
    ours = [p for p in ours if p.endswith("site-packages")]
    assert sysconfig.get_paths()["purelib"] in ours
    assert not [p for p in ours if (Path(p) / "trajcache").exists()]  # an editable install
    (Path(site) / "borrowed.pth").write_text("\n".join(ours) + "\n")
    return where / "bin"


@pytest.mark.slow
def test_a_plain_install_migrates_a_database_without_the_source_tree(
    wheel: Path, tmp_path: Path
) -> None:
    bin_dir = _isolated_install(wheel, tmp_path / "venv")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "TRAJCACHE_DATA_DIR": str(elsewhere)}
    where = subprocess.run(
        [str(bin_dir / "python"), "-c", "import importlib.resources as r; "
         "print(r.files('trajcache.db') / 'migrations' / 'env.py')"],
        cwd=elsewhere, env=env, capture_output=True, text=True, check=True,
    ).stdout.strip()  # fmt: skip
    assert Path(where).is_relative_to(tmp_path / "venv") and Path(where).is_file()
    done = subprocess.run(
        [str(bin_dir / "trajcache"), "migrate"],
        cwd=elsewhere,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    url = f"sqlite:///{elsewhere / 'trajcache.db'}"
    assert current_revision(url) is not None and f"{url} is at revision" in done.stdout
    engine = sa.create_engine(url)
    try:
        assert "trajectories" in sa.inspect(engine).get_table_names()
    finally:
        engine.dispose()


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
