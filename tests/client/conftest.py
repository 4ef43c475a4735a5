"""Client fixtures: the real app on SQLite and PostgreSQL, served on loopback or in process."""

from __future__ import annotations

import socket
import threading
from collections.abc import AsyncIterator, Iterator
from typing import Any

import httpx
import pytest
import uvicorn
from fastapi import FastAPI

from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.main import create_app
from trajcache_client import AsyncClient, Client, Retry

FAST_RETRY = Retry(retries=2, backoff_s=0.001, backoff_max_s=0.01)


def make_app(database_url: str, **overrides: Any) -> FastAPI:
    """The real app; planner workers start on the first miss that needs them."""
    overrides.setdefault("worker_prestart", False)
    return create_app(Settings(database_url=database_url, **overrides))


class LiveServer:
    """The app served by uvicorn on a loopback port, in a thread."""

    def __init__(self, app: FastAPI) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}"
        config = uvicorn.Config(app, log_level="warning", lifespan="on")
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.sock]})

    def __enter__(self) -> LiveServer:
        self.thread.start()
        up = wait_until(lambda: self.server.started or not self.thread.is_alive(), timeout_s=60)
        if not up or not self.server.started:
            raise RuntimeError("the live server did not start")
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=30)
        self.sock.close()


@pytest.fixture
def live_url(database_url: str) -> Iterator[str]:
    """Base URL of the app served on loopback."""
    with LiveServer(make_app(database_url)) as server:
        yield server.url


@pytest.fixture
def client(live_url: str) -> Iterator[Client]:
    """A blocking client of the live server."""
    with Client(live_url, retry=FAST_RETRY) as tc:
        yield tc


@pytest.fixture
async def async_client(database_url: str) -> AsyncIterator[AsyncClient]:
    """An asyncio client of the app in process (httpx.ASGITransport), lifespan included."""
    app = make_app(database_url)
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with AsyncClient("http://trajcache.test", transport=transport) as tc:
            yield tc


@pytest.fixture
def anyio_backend() -> str:
    """Async tests run on asyncio."""
    return "asyncio"
