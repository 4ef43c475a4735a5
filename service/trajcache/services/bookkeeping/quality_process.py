"""A planned trajectory's quality columns, computed in a process of their own.

The quality of a trajectory the planner just stored (`services.catalog.trajectories.
quality_columns`: its duration after time-optimal timing, its clearance in the scene) is
Python work: about 23 ms for an MBM Panda path (timing 15.6 ms, clearance 6.5 ms). The record
writer computes it after the answer, but in the service's process it held the interpreter's
lock that the next requests need: a cache hit asked right after a plan waited for it. Here the
writer hands it to one process of this machine and waits without that lock.

The process is shared by the service's contexts in this interpreter, started on the first job
and again after it died; a job that fails, or that the process does not answer within
`QUALITY_TIMEOUT_S`, leaves the columns empty (logged), as a metric that cannot be computed
always has. The model travels as its source, its mesh files spooled once (`jobs.spool`); the
process keeps the models, and the validators of the scenes, it built.
"""

from __future__ import annotations

import atexit
import logging
import multiprocessing
import sys
import threading
from collections.abc import Mapping
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures.process import BrokenProcessPool
from typing import Any

import numpy as np

from trajcache.core.config import Settings
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import ValidatorCache
from trajcache.jobs.local import init_worker
from trajcache.jobs.spool import ModelSpool
from trajcache.planning.problem import ModelSource
from trajcache.planning.run import model_from_source

logger = logging.getLogger(__name__)

__all__ = ["QUALITY_TIMEOUT_S", "quality_elsewhere", "stop_quality_process"]

QUALITY_TIMEOUT_S = 60.0  # a job not answered by then leaves its columns empty
_PRELOAD = ["trajcache.jobs.preload", "trajcache.planning.problem", __name__]

# In the quality process: the validators of the scenes it measured in (and their geometry).
_VALIDATORS = ValidatorCache()


class _Process:
    """The one quality process of this interpreter, and the spool of its models' files."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._executor: ProcessPoolExecutor | None = None
        self._spool = ModelSpool()

    def submit(
        self, source: ModelSource, states: np.ndarray, settings: Settings, scene: Scene | None
    ) -> tuple[ProcessPoolExecutor, Future[Mapping[str, Any] | None]]:
        """The job handed to the process (a new one if it died since the last job)."""
        spooled = self._spool.source(source)
        executor = self._current()
        try:
            return executor, executor.submit(_columns, spooled, states, settings, scene)
        except BrokenProcessPool:  # it died between jobs: a new one takes this
            self.retire(executor)
            executor = self._current()
            return executor, executor.submit(_columns, spooled, states, settings, scene)

    def _current(self) -> ProcessPoolExecutor:
        with self._lock:
            if self._executor is None:
                method = "forkserver" if sys.platform.startswith("linux") else "spawn"
                context = multiprocessing.get_context(method)
                if method == "forkserver":  # as the planner pool's: whichever starts it first
                    context.set_forkserver_preload(_PRELOAD)
                self._executor = ProcessPoolExecutor(1, mp_context=context, initializer=init_worker)
            return self._executor

    def retire(self, executor: ProcessPoolExecutor) -> None:
        """Stop `executor` (broken or stuck) now; the next job starts a new process."""
        with self._lock:
            if self._executor is executor:
                self._executor = None
        for process in list((getattr(executor, "_processes", None) or {}).values()):
            process.kill()  # a stuck job's process must go: the only handle on it is private
        executor.shutdown(wait=False, cancel_futures=True)

    def stop(self) -> None:
        with self._lock:
            executor, self._executor = self._executor, None
        if executor is not None:
            executor.shutdown(wait=True, cancel_futures=True)
        self._spool.close()


_PROCESS = _Process()
atexit.register(_PROCESS.stop)


def quality_elsewhere(
    source: ModelSource, states: np.ndarray, settings: Settings, scene: Scene | None
) -> Mapping[str, Any] | None:
    """The quality columns of `states` of model `source` in `scene`, computed in the quality
    process; None when they could not be (the reason is logged)."""
    executor, future = _PROCESS.submit(source, np.asarray(states, dtype=float), settings, scene)
    try:
        return future.result(timeout=QUALITY_TIMEOUT_S)
    except FutureTimeout:
        logger.warning("quality process gave no answer in %g s; restarted", QUALITY_TIMEOUT_S)
        _PROCESS.retire(executor)
    except BrokenProcessPool:
        logger.warning("quality process died; restarted for the next job")
        _PROCESS.retire(executor)
    except Exception:  # the job raised
        logger.warning("quality could not be computed in its process", exc_info=True)
    return None


def stop_quality_process() -> None:
    """Stop the quality process (it starts again on the next job)."""
    _PROCESS.stop()


def _columns(
    source: ModelSource, states: np.ndarray, settings: Settings, scene: Scene | None
) -> Mapping[str, Any] | None:
    """In the quality process: the columns, as the service would compute them itself."""
    from trajcache.services.catalog.trajectories import quality_columns

    model = model_from_source(source)
    return quality_columns(model, states, settings, scene, validators=_VALIDATORS)
