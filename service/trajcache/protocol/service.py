"""Start the real service (uvicorn on loopback) in a subprocess for benchmarks."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx

_PIDS: dict[str, int] = {}  # base URL → pid of the service started by running_service


def server_cpu_seconds(base: str) -> float:
    """CPU time (user + system, s) used so far by the HTTP processes of the service at `base`
    (the planner pool's processes, forked from a forkserver, are left out); Linux only (read
    from /proc), NaN elsewhere."""
    root = _PIDS.get(base)
    proc = Path("/proc")
    if root is None or not (proc / str(root)).exists():
        return float("nan")
    tick = os.sysconf("SC_CLK_TCK")
    stats: dict[int, tuple[int, float]] = {}  # pid → (parent pid, cpu seconds)
    for entry in proc.iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:  # the process ended meanwhile
            continue
        if b"forkserver" in cmdline or b"resource_tracker" in cmdline:
            continue
        stats[int(entry.name)] = (int(fields[1]), (int(fields[11]) + int(fields[12])) / tick)
    family, total, grew = {root}, 0.0, True
    while grew:
        grew = False
        for pid, (parent, _) in stats.items():
            if parent in family and pid not in family:
                family.add(pid)
                grew = True
    for pid in family:
        total += stats.get(pid, (0, 0.0))[1]
    return total


def free_port() -> int:
    """An unused TCP port on loopback."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@contextmanager
def running_service(
    database_url: str | None = None, *, workers: int = 1, env: dict[str, str] | None = None
) -> Iterator[str]:
    """Run `trajcache serve` on a free port; yield its base URL; stop it afterwards."""
    port = free_port()
    with tempfile.TemporaryDirectory() as tmp:
        url = database_url or f"sqlite:///{Path(tmp) / 'bench.db'}"
        child_env = {**os.environ, "TRAJCACHE_DATABASE_URL": url, "TRAJCACHE_LOG_LEVEL": "warning"}
        child_env.update(env or {})
        cmd = [sys.executable, "-m", "trajcache.cli", "serve", "--host", "127.0.0.1",
               "--port", str(port), "--workers", str(workers)]  # fmt: skip
        proc = subprocess.Popen(cmd, env=child_env, cwd=tmp)
        base = f"http://127.0.0.1:{port}"
        _PIDS[base] = proc.pid
        try:
            deadline = time.monotonic() + 60
            while True:
                try:
                    if httpx.get(f"{base}/readyz", timeout=1.0).status_code == 200:
                        break
                except httpx.HTTPError:
                    pass
                if proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("the service did not start")
                time.sleep(0.2)
            yield base
        finally:
            _PIDS.pop(base, None)
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
