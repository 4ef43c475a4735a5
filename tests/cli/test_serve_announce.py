"""`trajcache serve` says "serving on" once the service answers, never before: after the kernels
are warmed (with their progress) and after the app's startup completed."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import httpx
import pytest

from tests.waiting import wait_until
from trajcache.cli.launch import free_port
from trajcache.cli.serve import announce_when_answering

START_S = 240.0  # a loaded 2-core machine may take minutes to warm and start


class _Healthy(BaseHTTPRequestHandler):
    def do_GET(self) -> None:
        self.send_response(200 if self.path == "/healthz" else 404)
        self.end_headers()

    def log_message(self, *_: object) -> None:
        pass


@contextmanager
def _answering(port: int) -> Iterator[None]:
    server = ThreadingHTTPServer(("127.0.0.1", port), _Healthy)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield
    finally:
        server.shutdown()
        server.server_close()


def test_the_line_waits_for_an_answer(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port()
    thread = announce_when_answering(f"http://127.0.0.1:{port}", "serving now", interval_s=0.05)
    time.sleep(0.5)  # nothing listens yet: ten refused probes
    assert thread.is_alive() and "serving now" not in capsys.readouterr().err
    with _answering(port):
        thread.join(timeout=5)
    assert not thread.is_alive()
    assert capsys.readouterr().err == "serving now\n"


@pytest.mark.slow
def test_serve_says_it_serves_after_its_startup(tmp_path: Path) -> None:
    port = free_port()
    env = {
        **os.environ,
        "TRAJCACHE_DATABASE_URL": f"sqlite:///{tmp_path / 'cache.db'}",
        "TRAJCACHE_WORKER_BACKEND": "none",
        "TRAJCACHE_LOG_LEVEL": "info",
    }
    cmd = [sys.executable, "-m", "trajcache.cli", "serve", "--port", str(port)]
    stderr = tmp_path / "stderr.log"
    with stderr.open("wb") as err:
        process = subprocess.Popen(
            cmd, env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=err
        )
    try:
        said = wait_until(
            lambda: process.poll() is not None or "serving on" in stderr.read_text(),
            timeout_s=START_S,
            interval_s=0.2,
        )
        text = stderr.read_text()
        assert said and process.poll() is None, text[-3000:]
        assert httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=5).status_code == 200
    finally:
        process.terminate()
        process.wait(timeout=30)
    lines = text.splitlines()

    def first(needle: str) -> int:
        return next(i for i, line in enumerate(lines) if needle in line)

    assert first("kernels 1/") < first("kernels ready in") < first("Waiting for application")
    assert first("Application startup complete") < first("serving on")
    assert f"trajcache serving on http://127.0.0.1:{port}" in lines[first("serving on")]
