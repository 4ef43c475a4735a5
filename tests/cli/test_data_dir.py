"""Every command finds the same database wherever it runs: a relative SQLite path is in
TRAJCACHE_DATA_DIR; a command that only reads refuses a database that is not there, in one line
that names it and says how to migrate it, and creates nothing."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest
import sqlalchemy as sa
from alembic.script import ScriptDirectory
from typer.testing import CliRunner

from tests.waiting import wait_until
from trajcache.cli import app
from trajcache.cli.launch import free_port
from trajcache.db.migrate import alembic_config


@pytest.fixture
def data_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The data directory (not created yet), the default database URL, the cwd elsewhere."""
    monkeypatch.delenv("TRAJCACHE_DATABASE_URL", raising=False)
    data = tmp_path / "data"
    monkeypatch.setenv("TRAJCACHE_DATA_DIR", str(data))
    monkeypatch.chdir(_directory(tmp_path / "elsewhere"))
    return data


def _directory(path: Path) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    return path


def _one_error_line(output: str) -> str:
    lines = output.strip().splitlines()
    assert len(lines) == 1, output
    return lines[0]


READ_ONLY = [
    ["export"],
    ["prune", "--cap", "5"],
    ["prune", "--cap", "5", "--apply"],
    ["keys", "list"],
    ["keys", "revoke", "1"],
]


@pytest.mark.parametrize("args", READ_ONLY, ids=" ".join)
def test_a_missing_database_is_one_line_that_says_how_to_migrate_it(
    data_dir: Path, tmp_path: Path, args: list[str]
) -> None:
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2 and isinstance(result.exception, SystemExit), result.output
    line = _one_error_line(result.output)
    database = data_dir / "trajcache.db"
    assert line.startswith(f"error: no trajcache database at {database}")
    assert f"trajcache migrate --database-url sqlite:///{database}" in line
    assert not data_dir.exists() and list((tmp_path / "elsewhere").iterdir()) == []


def test_an_import_that_may_not_migrate_needs_the_schema_too(data_dir: Path) -> None:
    export = Path("cache.jsonl")
    export.write_text('{"type": "header", "format": "trajcache-export", "version": 1}\n')
    result = CliRunner().invoke(app, ["import", str(export), "--no-migrate"])
    assert result.exit_code == 2
    assert "trajcache migrate --database-url" in _one_error_line(result.output)
    assert not data_dir.exists()


def test_a_database_without_the_schema_is_named_without_a_traceback(
    data_dir: Path, tmp_path: Path
) -> None:
    database = _directory(data_dir) / "trajcache.db"
    with sa.create_engine(f"sqlite:///{database}").begin() as conn:
        conn.execute(sa.text("CREATE TABLE unrelated (id INTEGER)"))
    done = subprocess.run(
        [sys.executable, "-m", "trajcache.cli", "export"],
        cwd=tmp_path / "elsewhere",
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2 and done.stdout == ""
    line = _one_error_line(done.stderr)
    assert f"the database sqlite:///{database} has no trajcache schema" in line
    assert f"trajcache migrate --database-url sqlite:///{database}" in line


def test_a_database_behind_the_latest_revision_must_be_upgraded(data_dir: Path) -> None:
    url = f"sqlite:///{data_dir / 'old.db'}"
    migrated = CliRunner().invoke(app, ["migrate", "--revision", "0001", "--database-url", url])
    assert migrated.exit_code == 0, migrated.output
    result = CliRunner().invoke(app, ["export", "--database-url", "sqlite:///old.db"])
    assert result.exit_code == 2
    line = _one_error_line(result.output)
    head = ScriptDirectory.from_config(alembic_config(url)).get_current_head()
    assert head != "0001"
    assert f"is at schema revision 0001, not {head}" in line and f"--database-url {url}" in line


@contextmanager
def _running_service(cwd: Path) -> Iterator[str]:
    """`trajcache serve` with the default database, started in `cwd`; its base URL."""
    port = free_port()
    env = {
        **os.environ,
        "TRAJCACHE_WORKER_BACKEND": "none",
        "TRAJCACHE_LOG_LEVEL": "warning",
    }
    cmd = [sys.executable, "-m", "trajcache.cli", "serve", "--port", str(port)]
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stderr=subprocess.DEVNULL)
    base = f"http://127.0.0.1:{port}"
    try:
        ready = wait_until(lambda: _ready(base) or proc.poll() is not None, timeout_s=120)
        assert ready and proc.poll() is None, "the service did not start"
        yield base
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def _ready(base: str) -> bool:
    try:
        return httpx.get(f"{base}/readyz", timeout=2).status_code == 200
    except httpx.TransportError:
        return False


@pytest.mark.slow
def test_a_key_created_anywhere_guards_the_service_started_elsewhere(
    data_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    runner = CliRunner()
    monkeypatch.chdir(_directory(tmp_path / "one"))
    assert runner.invoke(app, ["migrate"]).exit_code == 0
    monkeypatch.chdir(_directory(tmp_path / "two"))
    created = runner.invoke(app, ["keys", "create", "--name", "ops", "--role", "admin"])
    assert created.exit_code == 0, created.output
    secret = created.stdout.strip().splitlines()[-1]
    assert [p.name for p in data_dir.glob("*.db")] == ["trajcache.db"]
    with _running_service(_directory(tmp_path / "three")) as base:
        assert httpx.get(f"{base}/v1/robot-models").status_code == 401
        with_key = httpx.get(f"{base}/v1/robot-models", headers={"X-API-Key": secret})
        assert with_key.status_code == 200, with_key.text
    for cwd in ("one", "two", "three"):
        assert list((tmp_path / cwd).iterdir()) == [], cwd
