"""What a Celery worker plans with: robot models by id and scenes by hash, from the database.

A task message names its model and scene (`trajcache.jobs.wire`); a worker process reads each
one it does not hold yet from the database the service writes to (the worker is configured with
the same `TRAJCACHE_DATABASE_URL`) and keeps the most recently used ones, so a model's URDF and
meshes cross the network once per worker process, not with every task.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, TypeVar

from sqlalchemy.orm import Session, sessionmaker

from trajcache.core.lru import LRU
from trajcache.db.session import make_engine, make_sessionmaker
from trajcache.db.sources import read_model_source, read_scene_payload
from trajcache.planning.problem import ModelSource, SceneSource

__all__ = ["MissingSourceError", "WorkerSources"]

T = TypeVar("T")

MODELS_KEPT = 8  # as many as `run_planning` keeps built (planning.run.MODEL_CACHE_SIZE)
SCENES_KEPT = 64


class MissingSourceError(LookupError):
    """The worker's database holds no model or scene of that name."""


class WorkerSources:
    """Model and scene sources read from the database at `database_url` on first use (LRU)."""

    def __init__(
        self,
        database_url: str,
        *,
        models: int = MODELS_KEPT,
        scenes: int = SCENES_KEPT,
    ) -> None:
        self.database_url = database_url
        self._models: LRU[str, ModelSource] = LRU(capacity=models)
        self._scenes: LRU[str, SceneSource] = LRU(capacity=scenes)
        self._sessions: sessionmaker[Session] | None = None
        self._lock = threading.Lock()
        self.reads = 0  # database reads so far

    def model(self, model_id: str) -> ModelSource:
        """The source of model `model_id` (MissingSourceError if the database lacks it)."""
        return self._models.get_or_build(
            model_id,
            lambda: _found(
                self._read(lambda s: read_model_source(s, model_id)),
                f"robot model {model_id!r} not found",
            ),
        )

    def scene(self, scene_hash: str, payload: dict[str, Any] | None) -> SceneSource:
        """The scene `scene_hash`: its `payload` if it came with one, else the stored one."""
        if payload is not None:
            return SceneSource(scene_hash, payload)
        return self._scenes.get_or_build(
            scene_hash,
            lambda: SceneSource(
                scene_hash,
                _found(
                    self._read(lambda s: read_scene_payload(s, scene_hash)),
                    f"scene {scene_hash!r} not found",
                ),
                stored=True,
            ),
        )

    def _read(self, read_fn: Callable[[Session], T]) -> T:
        with self._lock:  # the engine is made in the worker process, on its first read
            if self._sessions is None:
                self._sessions = make_sessionmaker(make_engine(self.database_url, pool_size=1))
            sessions = self._sessions
            self.reads += 1
        with sessions() as session:
            return read_fn(session)


def _found(value: T | None, missing: str) -> T:
    if value is None:
        raise MissingSourceError(missing)
    return value
