"""Liveness, readiness, and 503s while the database is down (and recovery when it is back)."""

from __future__ import annotations

import http.client
import json
import socket
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
import uvicorn
from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail, register
from tests.conftest import POSTGRES_URL
from tests.proxy import TcpProxy
from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.main import create_app


def test_healthz_and_readyz(app_client: TestClient) -> None:
    assert app_client.get("/healthz").json() == {"status": "ok"}
    response = app_client.get("/readyz")
    assert response.status_code == 200
    assert response.json() == {"status": "ready"}


def test_unreachable_database_is_503_but_alive(caplog: pytest.LogCaptureFixture) -> None:
    settings = Settings(database_url="postgresql+psycopg://postgres@127.0.0.1:1/none")
    with TestClient(create_app(settings, migrate=False)) as client:
        assert client.get("/healthz").status_code == 200
        for url in ("/readyz", "/v1/robots/r1", "/v1/trajectories"):
            reply = client.get(url)
            # Where the database is and what its driver said stay in the log.
            assert reply.status_code == 503, reply.text
            assert reply.json() == {"detail": "the database is unavailable"}
    assert "127.0.0.1" in caplog.text and "port 1" in caplog.text


def test_unknown_route_is_404_with_detail(app_client: TestClient) -> None:
    assert_detail(app_client.get("/v1/nothing-here"), 404)


@pytest.fixture
def proxy() -> Iterator[TcpProxy]:
    proxy = TcpProxy(("127.0.0.1", 5432))
    proxy.start()
    yield proxy
    proxy.stop()


@pytest.mark.postgres
def test_database_outage_is_503_and_the_service_recovers(
    postgres_url: str, proxy: TcpProxy
) -> None:
    url = postgres_url.replace("127.0.0.1:5432", f"127.0.0.1:{proxy.port}")
    assert url != postgres_url and POSTGRES_URL in postgres_url
    with TestClient(create_app(Settings(database_url=url))) as client:
        model_id = register(client)["model_id"]
        assert client.get("/readyz").status_code == 200

        proxy.stop()  # the database "goes away": pooled connections are cut
        assert_detail(client.get("/readyz"), 503, "the database is unavailable")
        assert_detail(client.get("/v1/robot-models"), 503, "the database is unavailable")
        assert client.get("/healthz").status_code == 200

        proxy.start()  # it comes back: no restart needed
        # A connection the outage left in the pool may fail its first statement, once (a 503:
        # `db.session._ping_idle_connections`); the disconnect invalidates the pool.
        assert wait_until(lambda: client.get("/readyz").status_code == 200, timeout_s=10.0)
        response = client.get("/v1/robot-models")
        assert response.status_code == 200
        assert [m["model_id"] for m in response.json()["items"]] == [model_id]


def test_unexpected_errors_are_logged_500s(
    database_url: str, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    from trajcache.api.routes import robots

    def broken(**_kwargs: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr(robots, "get_robot", broken)
    app = create_app(Settings(database_url=database_url))
    with TestClient(app, raise_server_exceptions=False) as client:
        assert_detail(client.get("/v1/robots/r1"), 500, "internal server error")
    assert any("boom" in (r.exc_text or "") for r in caplog.records if r.levelname == "ERROR")


def test_a_500_leaves_the_keep_alive_connection_usable(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    from trajcache.api.routes import robots

    def broken(**_kwargs: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr(robots, "get_robot", broken)
    app = create_app(Settings(database_url=f"sqlite:///{tmp_path / 'k.db'}", worker_prestart=False))
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        assert wait_until(lambda: server.started, timeout_s=30), "the server did not start"
        connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        connection.request("GET", "/v1/robots/r1")
        failed = connection.getresponse()
        body = json.loads(failed.read())
        assert failed.status == 500
        assert failed.getheader("connection") != "close"
        error_id = body["error_id"]
        assert body["detail"] == f"internal server error (error id {error_id})"
        connection.request("GET", "/healthz")  # the same connection
        assert connection.getresponse().status == 200
        connection.close()
        logged = [r for r in caplog.records if r.levelname == "ERROR" and error_id in r.message]
        assert logged and "boom" in (logged[0].exc_text or "")
    finally:
        server.should_exit = True
        thread.join(timeout=30)
