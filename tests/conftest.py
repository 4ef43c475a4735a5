"""Shared fixtures: real PostgreSQL and Redis when present; skipped (failed in CI) when not."""

from __future__ import annotations

import os
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest

REQUIRE_SERVICES = os.environ.get("TRAJCACHE_REQUIRE_SERVICES", "") == "1"
# `trajcache import` run in a test's own process would lower that process's CPU priority for
# the rest of the run (its default niceness): the suite's workers keep theirs.
os.environ.setdefault("TRAJCACHE_IMPORT_NICENESS", "0")
POSTGRES_URL = os.environ.get(
    "TRAJCACHE_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test"
)
REDIS_URL = os.environ.get("TRAJCACHE_TEST_REDIS_URL", "redis://127.0.0.1:6379/15")
# Under pytest-xdist, worker gwN takes the Redis database N below the configured one, so that
# parallel Celery tests never take each other's tasks. (PostgreSQL tests get a schema each.)
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw")
if _WORKER.isdigit() and int(_WORKER) > 0:
    _base, _, _db = REDIS_URL.rpartition("/")
    REDIS_URL = f"{_base}/{(int(_db or 0) - int(_WORKER)) % 16}"


def _port_open(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=1.0):
            return True
    except OSError:
        return False


def require_service(name: str, host: str, port: int) -> None:
    """Skip when the server is missing, or fail when CI says it must be there."""
    if _port_open(host, port):
        return
    message = f"{name} is not reachable at {host}:{port}"
    if REQUIRE_SERVICES:
        pytest.fail(f"{message} and TRAJCACHE_REQUIRE_SERVICES=1")
    pytest.skip(message)


@pytest.fixture
def postgres_url() -> Iterator[str]:
    """URL of an empty schema on the local PostgreSQL server (dropped afterwards)."""
    require_service("PostgreSQL", "127.0.0.1", 5432)
    import uuid

    import sqlalchemy as sa

    schema = f"t_{uuid.uuid4().hex[:12]}"
    admin = sa.create_engine(POSTGRES_URL, isolation_level="AUTOCOMMIT", pool_pre_ping=True)
    with admin.connect() as conn:
        conn.execute(sa.text(f'CREATE SCHEMA "{schema}"'))
    try:
        yield f"{POSTGRES_URL}?options=-csearch_path%3D{schema}"
    finally:
        with admin.connect() as conn:
            conn.execute(sa.text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def database_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """An empty database: a SQLite file, or a fresh PostgreSQL schema."""
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'test.db'}"
    return str(request.getfixturevalue("postgres_url"))


@pytest.fixture
def migrated_url(database_url: str) -> str:
    """`database_url` with the schema migrated to the latest revision."""
    from trajcache.db import migrate

    migrate.upgrade(database_url)
    return database_url


@pytest.fixture
def redis_url() -> str:
    """URL of a Redis database reserved for tests."""
    require_service("Redis", "127.0.0.1", 6379)
    return REDIS_URL


@pytest.fixture(scope="session", autouse=True)
def data_dir_of_tests(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """TRAJCACHE_DATA_DIR in a temporary directory: a default database is never the user's."""
    with pytest.MonkeyPatch.context() as patch:
        path = tmp_path_factory.mktemp("data")
        patch.setenv("TRAJCACHE_DATA_DIR", str(path))
        yield path


@pytest.fixture(scope="session", autouse=True)
def compiled_kernels() -> None:
    """The compiled kernels in numba's on-disk cache before any test starts a server (a server
    compiling them inside a request would time out)."""
    from trajcache.planning.warm import warm

    warm()
