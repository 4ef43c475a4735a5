"""Start `trajcache serve` in child processes on loopback and wait until each is ready.

The one way a real service is started for measurement: by `trajcache demo`, by the benchmarks
(`bench/`) and by their tests. Each service gets a free port, its own working directory and,
unless a database URL is given, a temporary SQLite database; it is ready when `GET /readyz`
answers 200. Services started together start side by side and are awaited together; `ready_fn`
hears of each one as it becomes ready.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

from trajcache_client import NO_RETRY, Client, TrajcacheError

_PIDS: dict[str, int] = {}  # base URL → pid of a service started here and still running


def free_port() -> int:
    """An unused TCP port on loopback."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def service_pid(base: str) -> int | None:
    """The pid of the running service at `base` started here (None for any other)."""
    return _PIDS.get(base)


def _stop(proc: subprocess.Popen[bytes]) -> None:
    proc.terminate()
    try:
        proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _answers_ready(base: str) -> bool:
    """Whether the service at `base` answers GET /readyz within 2 s."""
    try:
        with Client(base, timeout=2.0, retry=NO_RETRY) as client:
            client.ready()
    except TrajcacheError:
        return False
    return True


ReadyFn = Callable[[int, str], None]  # (index of the service, its base URL)


def _wait_ready(
    procs: Sequence[subprocess.Popen[bytes]],
    bases: list[str],
    deadline_s: float,
    ready_fn: ReadyFn | None = None,
) -> None:
    waiting = set(range(len(procs)))
    limit = time.monotonic() + deadline_s
    while waiting:
        for i in sorted(waiting):
            if procs[i].poll() is not None:
                raise RuntimeError(f"the service for {bases[i]} exited while starting")
            if _answers_ready(bases[i]):
                waiting.discard(i)
                if ready_fn is not None:
                    ready_fn(i, bases[i])
        if waiting and time.monotonic() > limit:
            raise RuntimeError(f"{len(waiting)} services not ready after {deadline_s:.0f} s")
        time.sleep(0.2)


@contextmanager
def running_services(
    database_urls: Sequence[str | None],
    *,
    workers: int = 1,
    env: Mapping[str, str] | None = None,
    deadline_s: float = 60.0,
    quiet: bool = False,
    ready_fn: ReadyFn | None = None,
) -> Iterator[list[str]]:
    """Run one service per database URL (None: temporary SQLite); yield their base URLs.

    `env` adds TRAJCACHE_* settings; `quiet` drops the services' standard output; `ready_fn` is
    called with each service's index and base URL as it becomes ready."""
    with ExitStack() as stack:
        procs, bases = [], []
        for url in database_urls:
            tmp = stack.enter_context(tempfile.TemporaryDirectory())
            port = free_port()
            child_env = {
                **os.environ,
                "TRAJCACHE_DATABASE_URL": url or f"sqlite:///{Path(tmp) / 'cache.db'}",
                "TRAJCACHE_LOG_LEVEL": "warning",
                **(env or {}),
            }
            cmd = [sys.executable, "-m", "trajcache.cli", "serve", "--host", "127.0.0.1",
                   "--port", str(port), "--workers", str(workers)]  # fmt: skip
            stdout = subprocess.DEVNULL if quiet else None
            proc = subprocess.Popen(cmd, env=child_env, cwd=tmp, stdout=stdout)
            base = f"http://127.0.0.1:{port}"
            stack.callback(_stop, proc)
            stack.callback(_PIDS.pop, base, None)
            _PIDS[base] = proc.pid
            procs.append(proc)
            bases.append(base)
        _wait_ready(procs, bases, deadline_s, ready_fn)
        yield bases


@contextmanager
def running_service(
    database_url: str | None = None,
    *,
    workers: int = 1,
    env: Mapping[str, str] | None = None,
    deadline_s: float = 60.0,
) -> Iterator[str]:
    """Run one service (None: on a temporary SQLite database); yield its base URL."""
    with running_services([database_url], workers=workers, env=env, deadline_s=deadline_s) as bases:
        yield bases[0]
