"""Liveness, readiness, and 503s while the database is down (and recovery when it is back)."""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail, register
from tests.conftest import POSTGRES_URL
from trajcache.core.config import Settings
from trajcache.main import create_app


def test_healthz_and_readyz(app_client: TestClient) -> None:
    assert app_client.get("/healthz").json() == {"status": "ok"}
    response = app_client.get("/readyz")
    assert response.status_code == 200
    assert response.json() == {"status": "ready"}


def test_unreachable_database_is_503_but_alive() -> None:
    settings = Settings(database_url="postgresql+psycopg://postgres@127.0.0.1:1/none")
    with TestClient(create_app(settings, migrate=False)) as client:
        assert client.get("/healthz").status_code == 200
        assert_detail(client.get("/readyz"), 503, "database unavailable")
        assert_detail(client.get("/v1/robots/r1"), 503, "database unavailable")
        assert_detail(client.get("/v1/trajectories"), 503, "database unavailable")


def test_unknown_route_is_404_with_detail(app_client: TestClient) -> None:
    assert_detail(app_client.get("/v1/nothing-here"), 404)


class TcpProxy:
    """Forwards a local port to PostgreSQL; `stop()` drops every connection, `start()` resumes."""

    def __init__(self, target: tuple[str, int]) -> None:
        self.target = target
        probe = socket.socket()
        probe.bind(("127.0.0.1", 0))
        self.port = probe.getsockname()[1]
        probe.close()
        self._server: socket.socket | None = None
        self._conns: list[socket.socket] = []
        self._lock = threading.Lock()

    def start(self) -> None:
        server = socket.socket()
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind(("127.0.0.1", self.port))
        server.listen(16)
        self._server = server
        threading.Thread(target=self._accept, args=(server,), daemon=True).start()

    def stop(self) -> None:
        if self._server is not None:
            with contextlib.suppress(OSError):  # wakes the thread blocked in accept()
                self._server.shutdown(socket.SHUT_RDWR)
            self._server.close()
            self._server = None
        with self._lock:
            for conn in self._conns:
                with contextlib.suppress(OSError):
                    conn.shutdown(socket.SHUT_RDWR)
                conn.close()
            self._conns.clear()

    def _accept(self, server: socket.socket) -> None:
        while True:
            try:
                client, _ = server.accept()
            except OSError:
                return
            upstream = socket.create_connection(self.target)
            with self._lock:
                self._conns += [client, upstream]
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pipe, args=(a, b), daemon=True).start()

    @staticmethod
    def _pipe(src: socket.socket, dst: socket.socket) -> None:
        try:
            while data := src.recv(65536):
                dst.sendall(data)
        except OSError:
            pass
        finally:
            for s in (src, dst):
                with contextlib.suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)


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
        assert_detail(client.get("/readyz"), 503, "database unavailable")
        assert_detail(client.get("/v1/robot-models"), 503, "database unavailable")
        assert client.get("/healthz").status_code == 200

        proxy.start()  # it comes back: no restart needed
        assert client.get("/readyz").status_code == 200
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
