"""`trajcache serve` as a process: how it stops, and what it leaves behind when it is killed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest

from tests.waiting import wait_until
from trajcache.cli.launch import free_port

pytestmark = pytest.mark.slow

WORKERS = 2
START_S = 240.0  # a loaded 2-core machine takes minutes to start a service and its workers
EXIT_S = 30.0  # the workers of a killed service notice it at once; this is slack


@dataclass(frozen=True)
class Proc:
    """A process, told apart from a later one with the same pid by its start time."""

    pid: int
    started: int


def _stat(pid: int) -> list[str] | None:
    """The fields of /proc/<pid>/stat after the command name (state first), or None."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text.rsplit(")", 1)[1].split()


def _proc(pid: int) -> Proc | None:
    fields = _stat(pid)
    return None if fields is None else Proc(pid, int(fields[19]))


def children(pid: int) -> list[int]:
    """Pids of the processes whose parent is `pid`."""
    found = []
    for entry in Path("/proc").iterdir():
        fields = _stat(int(entry.name)) if entry.name.isdigit() else None
        if fields is not None and int(fields[1]) == pid:
            found.append(int(entry.name))
    return found


def descendants(pid: int) -> list[Proc]:
    """The processes below `pid`, children before grandchildren."""
    found, level = [], children(pid)
    while level:
        found += [p for p in map(_proc, level) if p is not None]
        level = [c for parent in level for c in children(parent)]
    return found


def alive(proc: Proc) -> bool:
    """Whether `proc` still runs (a zombie waiting to be reaped does not)."""
    fields = _stat(proc.pid)
    return fields is not None and fields[0] != "Z" and int(fields[19]) == proc.started


@dataclass(frozen=True)
class Server:
    process: subprocess.Popen[bytes]
    stderr: Path

    def planner_workers(self) -> list[int]:
        """The planner pool's workers: children of the children (the forkserver's)."""
        return [c for child in children(self.process.pid) for c in children(child)]


def _ready(base: str) -> bool:
    try:
        return httpx.get(f"{base}/readyz", timeout=2.0).status_code == 200
    except httpx.HTTPError:
        return False


@contextmanager
def serving(tmp_path: Path) -> Iterator[Server]:
    """`trajcache serve` on a SQLite file, ready, with its planner workers started."""
    port = free_port()
    env = {
        **os.environ,
        "TRAJCACHE_DATABASE_URL": f"sqlite:///{tmp_path / 'cache.db'}",
        "TRAJCACHE_WORKER_PROCESSES": str(WORKERS),
        "TRAJCACHE_LOG_LEVEL": "info",
    }
    cmd = [sys.executable, "-m", "trajcache.cli", "serve", "--host", "127.0.0.1", "--port",
           str(port)]  # fmt: skip
    stderr = tmp_path / "stderr.log"
    with stderr.open("wb") as err:
        process = subprocess.Popen(
            cmd, env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=err
        )
    server = Server(process, stderr)
    family: list[Proc] = []
    try:
        base = f"http://127.0.0.1:{port}"
        started = wait_until(
            lambda: (
                process.poll() is not None
                or (_ready(base) and len(server.planner_workers()) == WORKERS)
            ),
            timeout_s=START_S,
            interval_s=0.2,
        )
        assert started and process.poll() is None, stderr.read_text()[-3000:]
        family = descendants(process.pid)
        yield server
    finally:
        process.kill()
        process.wait()
        for proc in family:  # what a failed test left running
            if alive(proc):
                os.kill(proc.pid, signal.SIGKILL)


def test_a_killed_server_leaves_no_process_behind(tmp_path: Path) -> None:
    with serving(tmp_path) as server:
        family = descendants(server.process.pid)  # resource tracker, forkserver, workers
        assert len(family) == 2 + WORKERS, family
        server.process.send_signal(signal.SIGKILL)
        server.process.wait()
        gone = wait_until(lambda: not any(map(alive, family)), timeout_s=EXIT_S, interval_s=0.1)
        assert gone, f"still running: {[p.pid for p in family if alive(p)]}"


def test_sigterm_stops_the_server_with_status_0_and_no_warning(tmp_path: Path) -> None:
    with serving(tmp_path) as server:
        family = descendants(server.process.pid)
        server.process.send_signal(signal.SIGTERM)
        assert server.process.wait(timeout=EXIT_S) == 0
        assert wait_until(lambda: not any(map(alive, family)), timeout_s=EXIT_S, interval_s=0.1)
        stderr = server.stderr.read_text()
        assert "Application shutdown complete" in stderr
        assert "leaked" not in stderr and "resource_tracker" not in stderr, stderr
