"""PostgreSQL engines ping only pooled connections that sat idle, and replace dead ones."""

from __future__ import annotations

import pytest
import sqlalchemy as sa

from tests.waiting import wait_until
from trajcache.db import session as db_session
from trajcache.db.session import make_engine

pytestmark = pytest.mark.postgres


def _backend_pid(engine: sa.Engine) -> int:
    with engine.connect() as conn:
        return int(conn.execute(sa.text("SELECT pg_backend_pid()")).scalar_one())


def _terminate(url: str, pid: int) -> None:
    admin = sa.create_engine(url, isolation_level="AUTOCOMMIT")
    try:
        with admin.connect() as conn:
            conn.execute(sa.text("SELECT pg_terminate_backend(:pid)"), {"pid": pid})
    finally:
        admin.dispose()


def _backend_alive(url: str, pid: int) -> bool:
    admin = sa.create_engine(url, isolation_level="AUTOCOMMIT")
    try:
        with admin.connect() as conn:
            query = sa.text("SELECT count(*) FROM pg_stat_activity WHERE pid = :pid")
            return bool(conn.execute(query, {"pid": pid}).scalar())
    finally:
        admin.dispose()


def test_a_dead_idle_connection_is_replaced_before_use(
    postgres_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(db_session, "PING_IDLE_S", 0.0)  # every connection has sat idle too long
    engine = make_engine(postgres_url, pool_size=1)
    try:
        first = _backend_pid(engine)
        _terminate(postgres_url, first)
        assert wait_until(lambda: not _backend_alive(postgres_url, first))
        assert _backend_pid(engine) != first  # pinged, found dead, reconnected: no error
    finally:
        engine.dispose()


def test_a_connection_handed_back_moments_ago_is_not_pinged(postgres_url: str) -> None:
    engine = make_engine(postgres_url, pool_size=1)
    pings: list[object] = []
    ping = engine.dialect.do_ping

    def counted(dbapi_connection: object) -> bool:
        pings.append(dbapi_connection)
        return ping(dbapi_connection)

    engine.dialect.do_ping = counted  # type: ignore[method-assign]
    try:
        _backend_pid(engine)  # a new connection: pinged on its first checkout
        _backend_pid(engine)
        _backend_pid(engine)
        assert len(pings) == 1
    finally:
        engine.dispose()


def test_postgresql_connections_do_not_jit_compile(postgres_url: str) -> None:
    """Every pooled connection has JIT off (`session._without_jit`): the sync query's cost
    estimate passes `jit_above_cost` while an import is in flight, and compiling it cost each
    plan 55 ms. (A plain connection shows the server's default: on, on this machine.)"""
    plain = sa.create_engine(postgres_url.replace("postgresql://", "postgresql+psycopg://", 1))
    try:
        with plain.connect() as conn:
            default = conn.exec_driver_sql("SHOW jit").scalar()
    finally:
        plain.dispose()
    engine = make_engine(postgres_url, pool_size=1)
    try:
        with engine.connect() as first, engine.connect() as second:  # the overflow connects too
            assert first.exec_driver_sql("SHOW jit").scalar() == "off"
            assert second.exec_driver_sql("SHOW jit").scalar() == "off"
    finally:
        engine.dispose()
    assert default in ("on", "off")
