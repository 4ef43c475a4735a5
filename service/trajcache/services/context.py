"""Everything one service process shares between requests: settings, database, caches."""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field

import sqlalchemy as sa
from sqlalchemy import Engine
from sqlalchemy.exc import DBAPIError, SQLAlchemyError
from sqlalchemy.orm import Session, sessionmaker

from trajcache.cache.end_clearances import EndClearances
from trajcache.cache.memo import ValidationMemo
from trajcache.cache.ranking import RankingRules
from trajcache.core.budget import WorkBudget
from trajcache.core.config import Settings
from trajcache.core.lru import LRU
from trajcache.db.session import make_engine, make_sessionmaker
from trajcache.geometry.model.pin_kinematics import PinKinematics
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.variant import VariantCache, variant_cache
from trajcache.geometry.validation.validator import ValidatorCache
from trajcache.jobs.pool import PlannerPool, make_pool
from trajcache.services.bookkeeping.ranking_facts import RankingFactsCache
from trajcache.services.bookkeeping.records import PlanRecorder
from trajcache.services.catalog.certificates import CertificateStore
from trajcache.services.catalog.index_store import IndexStore
from trajcache.services.catalog.keys import KeyCache
from trajcache.services.catalog.models import ModelRegistry
from trajcache.services.catalog.scene_cache import SceneCache
from trajcache.services.errors import DATABASE_UNAVAILABLE, UnavailableError

_log = logging.getLogger(__name__)
KINEMATICS_CACHE_SIZE = 64  # models (as robots hold them) whose Pinocchio kinematics are kept


@dataclass
class ServiceContext:
    """The process-wide state of the service (one per app, stored on `app.state.ctx`).

    Every in-memory cache of the service process is one of its fields, built with it and
    emptied by `clear_caches`. (Worker processes keep their own, in `planning.run`.)
    """

    settings: Settings
    engine: Engine
    sessions: sessionmaker[Session]
    models: ModelRegistry
    scenes: SceneCache
    indexes: IndexStore
    keys: KeyCache
    memo: ValidationMemo  # key states already certified per model, scene and validator settings
    records: PlanRecorder  # plan bookkeeping, written off the request path
    ranking: RankingRules  # how lookup candidates are ordered before validation
    facts: RankingFactsCache = field(default_factory=RankingFactsCache)  # what ranking reads
    variants: VariantCache = field(default_factory=variant_cache)  # models as robots hold them
    validators: ValidatorCache = field(default_factory=ValidatorCache)  # and their geometry
    kinematics: LRU[RobotModel, PinKinematics] = field(  # Pinocchio's, for IK, by model object
        default_factory=lambda: LRU(capacity=KINEMATICS_CACHE_SIZE)
    )
    certificates: CertificateStore = field(default_factory=CertificateStore)  # what was proved
    end_clearances: EndClearances = field(default_factory=EndClearances)  # along stored ends
    measuring: WorkBudget = field(default_factory=WorkBudget)  # the writer's share for them
    planner: PlannerPool | None = None  # started by planner_pool(), closed by close()
    _planner_lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

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
            keys=KeyCache(ttl_s=settings.auth_cache_ttl_s),
            memo=ValidationMemo(),
            records=PlanRecorder(engine),
            ranking=RankingRules.from_settings(settings),
            facts=RankingFactsCache(ttl_s=settings.ranking_facts_ttl_s),
        )

    def clear_caches(self) -> None:
        """Empty every in-memory cache (the database stays the source of truth)."""
        self.models.clear()
        self.scenes.clear()
        self.indexes.clear_states()
        self.keys.clear()
        self.memo.clear()
        self.facts.clear()
        self.variants.clear()
        self.validators.clear()
        self.kinematics.clear()
        self.certificates.clear()
        self.end_clearances.clear()

    def ping(self) -> None:
        """Run `SELECT 1`; raise UnavailableError when the database cannot be reached."""
        try:
            with self.engine.connect() as conn:
                conn.execute(sa.text("SELECT 1"))
        except SQLAlchemyError as exc:
            cause = exc.orig if isinstance(exc, DBAPIError) else exc
            _log.warning("database unavailable: %s", _first_line(cause))
            raise UnavailableError(DATABASE_UNAVAILABLE) from exc

    def planner_pool(self) -> PlannerPool | None:
        """The fallback planner pool, started on first use; None when planning is off."""
        if self.planner is not None or self.settings.worker_backend == "none":
            return self.planner
        with self._planner_lock:
            if self.planner is None:
                self.planner = make_pool(self.settings)
        return self.planner

    def close(self) -> None:
        """Stop the planner pool, write pending plan records, release the database connections."""
        with self._planner_lock:
            planner, self.planner = self.planner, None
        if planner is not None:
            planner.close()
        self.records.close()
        self.engine.dispose()


def _first_line(exc: BaseException | None) -> str:
    text = str(exc).strip() if exc is not None else ""
    return text.splitlines()[0] if text else type(exc).__name__
