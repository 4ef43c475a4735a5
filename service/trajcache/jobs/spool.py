"""Models' mesh files spooled to disk once, for the worker processes of this machine."""

from __future__ import annotations

import hashlib
import os
import pickle
import tempfile
import threading
from dataclasses import replace

from trajcache.core.lru import LRU
from trajcache.planning.problem import ModelSource

__all__ = ["SPOOLED_MODELS", "ModelSpool"]

SPOOLED_MODELS = 64  # models whose spooled source is remembered (their files stay spooled)


class ModelSpool:
    """The models' mesh files, each model's pickled once into a private directory that the
    workers read (`ModelSource.files_at`), so that a task carries only their file name.

    A worker reads them only to build a model it has not built yet (`planning.run`). The
    directory (mode 0700) is its owner's (a pool of worker processes), and goes with it.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._dir: tempfile.TemporaryDirectory[str] | None = None
        self._sources: LRU[str, ModelSource] = LRU(capacity=SPOOLED_MODELS)

    def source(self, model: ModelSource) -> ModelSource:
        """`model` with its files in the spool (as it is when it has none)."""
        if not model.files:
            return model
        with self._lock:
            spooled = self._sources.get(model.model_id)
            if spooled is not None and spooled.files_at and os.path.exists(spooled.files_at):
                return spooled
            if self._dir is None:
                self._dir = tempfile.TemporaryDirectory(prefix="trajcache-models-")
            name = hashlib.sha256(model.model_id.encode()).hexdigest()[:32]
            path = os.path.join(self._dir.name, f"{name}.pickle")
            with open(f"{path}.part", "wb") as out:
                pickle.dump(model.files, out, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(f"{path}.part", path)  # whole, or not there
            spooled = replace(model, files={}, files_at=path)
            self._sources.put(model.model_id, spooled)
            return spooled

    def close(self) -> None:
        with self._lock:
            if self._dir is not None:
                self._dir.cleanup()
                self._dir = None
            self._sources.clear()
