"""`trajcache robots fetch`: a supported robot's files, laid out as an upload resolves them,
with the lines that register them; without `example-robot-data`, what to install."""

from __future__ import annotations

import os
import subprocess
import sysconfig
import threading
import zipfile
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest
from starlette.requests import Request
from typer.testing import CliRunner

from trajcache.api.auth import presented_key
from trajcache.cli import app
from trajcache.cli.robots import RobotName
from trajcache.geometry.model.files import MeshResolver, unpack_archive
from trajcache.reference.example_robots import _MESH_URI, ROBOTS


def test_the_command_offers_every_supported_robot() -> None:
    assert sorted(r.value for r in RobotName) == sorted(ROBOTS)


def test_fetch_writes_the_files_and_prints_how_to_register_them(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["robots", "fetch", "panda", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "panda-meshes.zip",
        "panda.srdf",
        "panda.urdf",
    ]
    panda = ROBOTS["panda"]
    assert (tmp_path / "panda.urdf").read_text() == panda.urdf
    assert (tmp_path / "panda.srdf").read_text() == panda.srdf
    archive = (tmp_path / "panda-meshes.zip").read_bytes()
    with zipfile.ZipFile(tmp_path / "panda-meshes.zip") as written:
        assert all(name.startswith("robots/panda_description/") for name in written.namelist())
    resolver = MeshResolver(unpack_archive(archive))
    uris = {f"package://example-robot-data/robots/{p}" for p in _MESH_URI.findall(panda.urdf)}
    assert len(uris) > 10
    for uri in uris:  # every mesh the URDF names is in the archive, where the service looks
        resolver.resolve(uri)
    lines = result.stdout.splitlines()
    curl = (
        'curl -s -H "X-API-Key: ${TRAJCACHE_API_KEY:-}" http://127.0.0.1:8000/v1/robot-models '
        f"-F urdf=@{tmp_path}/panda.urdf"
    )
    assert any(line.startswith(curl) for line in lines), lines
    assert any(line.startswith("client.register_model(") for line in lines), lines


def test_without_example_robot_data_it_says_what_to_install(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    empty = {key: str(tmp_path / key) for key in ("purelib", "platlib", "data")}
    monkeypatch.setattr(sysconfig, "get_paths", lambda: empty)
    result = CliRunner().invoke(app, ["robots", "fetch", "ur5", "--out", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert "pip install 'trajcache[robots]'" in result.output
    assert not (tmp_path / "out").exists()


@pytest.fixture
def recorder() -> Iterator[tuple[str, list[dict[str, str]]]]:
    """An HTTP server on loopback that answers 201 and keeps each request's headers."""
    seen: list[dict[str, str]] = []

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self) -> None:
            self.rfile.read(int(self.headers.get("content-length", 0)))
            seen.append({k.lower(): v for k, v in self.headers.items()})
            self.send_response(201)
            self.send_header("content-length", "0")
            self.end_headers()

        def log_message(self, *_args: object) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}", seen
    finally:
        server.shutdown()
        server.server_close()


def _key_of(headers: dict[str, str]) -> str | None:
    """The key the service reads from these headers (`api.auth.presented_key`)."""
    raw = [(k.encode(), v.encode()) for k, v in headers.items()]
    return presented_key(Request({"type": "http", "headers": raw}))


def test_the_printed_curl_line_sends_the_key_the_service_reads(
    tmp_path: Path, recorder: tuple[str, list[dict[str, str]]]
) -> None:
    url, seen = recorder
    args = ["robots", "fetch", "panda", "--out", str(tmp_path), "--url", url]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    [curl] = [line for line in result.stdout.splitlines() if line.startswith("curl ")]
    env = {k: v for k, v in os.environ.items() if k != "TRAJCACHE_API_KEY"}
    for key in ("tc_secret-key", None):  # keys on; keys off (the variable unset)
        run_env = env if key is None else {**env, "TRAJCACHE_API_KEY": key}
        subprocess.run(["bash", "-c", curl], env=run_env, check=True, timeout=60)
        assert seen[-1]["content-type"].startswith("multipart/form-data")
        assert _key_of(seen[-1]) == key
    assert len(seen) == 2
    python = next(line for line in result.stdout.splitlines() if line.startswith("# Python:"))
    assert 'api_key=os.environ.get("TRAJCACHE_API_KEY")' in python
