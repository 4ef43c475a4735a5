"""Everything one service process shares between requests: settings, database, caches."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING

import sqlalchemy as sa
from sqlalchemy import Engine
from sqlalchemy.exc import DBAPIError, SQLAlchemyError
from sqlalchemy.orm import Session, sessionmaker

from trajcache.core.config import Settings
from trajcache.db.session import make_engine, make_sessionmaker
from trajcache.services.errors import UnavailableError
from trajcache.services.index_store import IndexStore
from trajcache.services.models import ModelRegistry
from trajcache.services.robots import SceneCache

if TYPE_CHECKING:
    from trajcache.jobs.pool import PlannerPool


@dataclass
class ServiceContext:
    """The process-wide state of the service (one per app, stored on `app.state.ctx`)."""

    settings: Settings
    engine: Engine
    sessions: sessionmaker[Session]
    models: ModelRegistry
    scenes: SceneCache
    indexes: IndexStore
    planner: PlannerPool | None = None  # set by whoever starts the worker pool

    @classmethod
    def create(cls, settings: Settings) -> ServiceContext:
        """A context with a fresh engine and empty caches for `settings`."""
        engine = make_engine(settings.database_url, pool_size=settings.db_pool_size)
        return cls(
            settings=settings,
            engine=engine,
            sessions=make_sessionmaker(engine),
            models=ModelRegistry(),
            scenes=SceneCache(),
            indexes=IndexStore(sync_interval_s=settings.index_sync_interval_s),
        )

    @contextmanager
    def session(self) -> Iterator[Session]:
        """A session that is closed (uncommitted work rolled back) on exit."""
        with self.sessions() as session:
            yield session

    def ping(self) -> None:
        """Run `SELECT 1`; raise UnavailableError when the database cannot be reached."""
        try:
            with self.engine.connect() as conn:
                conn.execute(sa.text("SELECT 1"))
        except DBAPIError as exc:
            raise UnavailableError(f"database unavailable: {_first_line(exc.orig)}") from exc
        except SQLAlchemyError as exc:
            raise UnavailableError(f"database unavailable: {_first_line(exc)}") from exc

    def close(self) -> None:
        """Release the database connections."""
        self.engine.dispose()


def _first_line(exc: BaseException | None) -> str:
    text = str(exc).strip() if exc is not None else ""
    return text.splitlines()[0] if text else type(exc).__name__
