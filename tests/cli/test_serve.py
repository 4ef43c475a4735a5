"""`trajcache serve` refuses what it cannot serve before it says it serves: a busy port, or a
database it may not migrate that is not ready; one line, a non-zero status, nothing created."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

from trajcache.cli.launch import free_port


def _serve(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """`trajcache serve ARGS` run to its end (a service that does start is a timeout)."""
    return subprocess.run(
        [sys.executable, "-m", "trajcache.cli", "serve", *args],
        cwd=cwd,
        env={**os.environ, "TRAJCACHE_WORKER_BACKEND": "none"},
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_a_busy_port_is_one_line_before_anything_is_served(tmp_path: Path) -> None:
    database = tmp_path / "cache.db"
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = _serve(tmp_path, "--port", str(port), "--database-url", f"sqlite:///{database}")
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.splitlines() == [
        f"error: cannot serve on 127.0.0.1:{port}: Address already in use "
        "(another service listens there; choose --port or TRAJCACHE_PORT)"
    ]
    assert not database.exists()


def test_serving_without_migrating_needs_a_ready_database(tmp_path: Path) -> None:
    database = tmp_path / "missing.db"
    port = str(free_port())
    done = _serve(
        tmp_path, "--no-migrate", "--port", port, "--database-url", f"sqlite:///{database}"
    )
    assert done.returncode == 2 and done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert line.startswith(f"error: no trajcache database at {database}")
    assert "trajcache migrate --database-url" in line
    assert not database.exists()
