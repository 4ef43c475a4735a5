"""Engine and session factories for SQLite (single node) and PostgreSQL (shared by replicas)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, TypeAlias

from sqlalchemy import Connection, Engine, create_engine, event
from sqlalchemy.engine import make_url
from sqlalchemy.exc import DisconnectionError
from sqlalchemy.orm import Session, sessionmaker

SQLITE_PRAGMAS = (
    "PRAGMA journal_mode=WAL",
    "PRAGMA foreign_keys=ON",
    "PRAGMA busy_timeout=5000",
    "PRAGMA synchronous=NORMAL",
)


# Where reads run: an ORM session (in its transaction) or a Core connection, which the plan flow's
# hit path uses for its reads (the session's transaction bookkeeping cost more than the query).
Reads: TypeAlias = Session | Connection


def connection_of(reads: Reads) -> Connection:
    """The Core connection that `reads` run on (a session's begins its transaction)."""
    return reads if isinstance(reads, Connection) else reads.connection()


def _set_sqlite_pragmas(dbapi_connection: Any, _connection_record: Any) -> None:
    cursor = dbapi_connection.cursor()
    try:
        for pragma in SQLITE_PRAGMAS:
            cursor.execute(pragma)
    finally:
        cursor.close()


def sqlite_file(url: str) -> Path | None:
    """The file of a SQLite URL; None for another database or an in-memory one."""
    sa_url = make_url(url)
    path = sa_url.database
    if sa_url.get_backend_name() != "sqlite" or not path or path == ":memory:":
        return None
    if path.startswith("file:"):  # a URI filename (`?uri=true`): memory or otherwise, leave it
        return None
    return Path(path)


def shown_url(url: str) -> str:
    """`url` as printed to people: the password hidden."""
    return make_url(url).render_as_string(hide_password=True)


def make_engine(url: str, *, pool_size: int = 10, echo: bool = False) -> Engine:
    """Create an engine configured for the database behind `url`."""
    sa_url = make_url(url)
    if sa_url.drivername == "postgresql":
        sa_url = sa_url.set(drivername="postgresql+psycopg")
    backend = sa_url.get_backend_name()
    if backend == "sqlite":
        engine = create_engine(sa_url, echo=echo, connect_args={"check_same_thread": False})
        event.listen(engine, "connect", _set_sqlite_pragmas)
        return engine
    if backend == "postgresql":
        engine = create_engine(sa_url, echo=echo, pool_size=pool_size, max_overflow=pool_size)
        _ping_idle_connections(engine)
        event.listen(engine, "connect", _without_jit)
        return engine
    return create_engine(sa_url, echo=echo, pool_pre_ping=True)


def _without_jit(dbapi_connection: Any, _record: Any) -> None:
    """Switch PostgreSQL's JIT compilation off for the service's connections.

    Every query here is small, but the planner's cost estimate of one can pass `jit_above_cost`:
    the replica sync's range join over the trajectories grows with the rows an import has
    inserted and not yet committed (2 million estimated rows at 60,000 in flight). JIT then
    compiled the query on every plan, 12 ms of code generation and 55 ms in all for a query
    that runs in 0.1 ms.
    """
    if dbapi_connection.info.server_version < 110000:  # no JIT before PostgreSQL 11
        return
    with dbapi_connection.cursor() as cursor:
        cursor.execute("SET jit = off")
    dbapi_connection.commit()


PING_IDLE_S = 1.0  # a pooled connection unused for longer is checked before it is handed out


def _ping_idle_connections(engine: Engine) -> None:
    """Pre-ping only connections that sat in the pool for more than PING_IDLE_S.

    A connection handed back moments ago is alive, and pinging it would cost every request a
    round trip. If the database went away meanwhile, the first statement fails (a 503), and
    SQLAlchemy invalidates the whole pool on that disconnect, so later checkouts reconnect.
    """

    def checkin(_dbapi_connection: Any, record: Any) -> None:
        record.info["checked_in_at"] = time.monotonic()

    def checkout(dbapi_connection: Any, record: Any, _proxy: Any) -> None:
        idle_since = record.info.get("checked_in_at")
        if idle_since is not None and time.monotonic() - idle_since < PING_IDLE_S:
            return
        try:
            engine.dialect.do_ping(dbapi_connection)
        except engine.dialect.loaded_dbapi.Error as exc:  # the pool reconnects and retries
            raise DisconnectionError(f"stale pooled connection: {exc}") from exc

    event.listen(engine, "checkin", checkin)
    event.listen(engine, "checkout", checkout)


def make_sessionmaker(engine: Engine) -> sessionmaker[Session]:
    """A session factory bound to `engine` (objects stay readable after commit)."""
    return sessionmaker(bind=engine, expire_on_commit=False)
