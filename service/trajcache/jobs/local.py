"""The local backend of the planner pool: a process pool on this machine, rebuilt on crashes."""

from __future__ import annotations

import contextlib
import hashlib
import multiprocessing
import os
import pickle
import signal
import sys
import tempfile
import threading
import time
from concurrent.futures import CancelledError, Future, ProcessPoolExecutor, wait
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field, replace

from trajcache.core.lru import LRU
from trajcache.jobs.backend import Meanwhile, TaskFn, error_result, run_meanwhile
from trajcache.jobs.threads import pin_one_thread
from trajcache.planning.problem import ModelSource, PlannerStatus, PlanningProblem, PlanResult

MIN_RETRY_BUDGET_S = 0.1  # a crashed task is not run again with less budget left than this
PARENT_GONE_EXIT = 70  # a worker's exit status when the process that started it is gone
MEANWHILE_AFTER_S = 0.001  # a task reaches its worker in a few tenths of a millisecond
SPOOLED_MODELS = 64  # models whose spooled source is remembered (their files stay spooled)


def _init_worker() -> None:
    """Runs first in every worker: Ctrl-C reaches the whole process group, but only the service
    decides when its workers stop (it stops them when it shuts down, or by dying); and one
    numeric thread, as the workers share the machine's cores."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _exit_with_parent()
    pin_one_thread()


def _exit_with_parent() -> None:
    """Exit as soon as the process that started this worker is gone, however it ended.

    A service killed with SIGKILL cannot stop its workers, and they would wait for work forever:
    each holds the pipe ends (its task queue's, the forkserver's) that would tell the others.
    multiprocessing gives every child a handle on its parent (the process that asked for it,
    not the forkserver that forked it), a pipe end that closes when the parent dies; a daemon
    thread waits on it. Without the workers, the forkserver and the resource tracker see their
    pipes close and exit too.
    """
    parent = multiprocessing.parent_process()
    if parent is None:
        return

    def watch() -> None:
        parent.join()  # returns once the parent is gone
        os._exit(PARENT_GONE_EXIT)  # no cleanup to wait for: the task's caller is gone

    threading.Thread(target=watch, name="trajcache-parent-watch", daemon=True).start()


def _warm_up(task_fn: TaskFn) -> None:
    """Runs in a fresh worker: unpickling `task_fn` has imported its module."""


@dataclass(eq=False)
class _Generation:
    """One executor, a slot per worker, and the unfinished futures with their deadlines."""

    executor: ProcessPoolExecutor
    slots: threading.BoundedSemaphore
    warm_ups: list[Future[None]]
    running: dict[Future[PlanResult], float] = field(default_factory=dict)


class LocalBackend:
    """A process pool on this machine; rebuilt when a worker crashes or a task overruns.

    A task is handed to the executor only once a worker is free (one slot per worker), so a
    request that times out waiting in line is told apart from one whose planning overran.

    A worker that dies (killed, out of memory, a crash in native code) breaks the whole executor:
    every task running on it fails, not only the dead worker's. Each of them is run again on the
    new workers, up to `crash_retries` times, with what is left of its planning budget.
    """

    def __init__(
        self,
        task_fn: TaskFn,
        *,
        processes: int,
        overrun_grace_s: float = 5.0,
        start_method: str | None = None,
        crash_retries: int = 0,
    ) -> None:
        if start_method is None:
            start_method = "forkserver" if sys.platform.startswith("linux") else "spawn"
        # Not "fork": the web server that owns the pool is multi-threaded.
        self._context = multiprocessing.get_context(start_method)
        if start_method == "forkserver":
            self._context.set_forkserver_preload(
                ["trajcache.jobs.preload", "trajcache.planning.problem", task_fn.__module__]
            )
        self.task_fn = task_fn
        self.processes = processes
        self.overrun_grace_s = overrun_grace_s
        self.crash_retries = crash_retries
        self._lock = threading.Lock()
        self._counts = {"crashes": 0, "recycles": 0}
        self._spool = _ModelSpool()
        self._generation: _Generation | None = self._new_generation()

    def _new_generation(self) -> _Generation:
        executor = ProcessPoolExecutor(
            max_workers=self.processes, mp_context=self._context, initializer=_init_worker
        )
        # Start the workers (and import the task's module) now, not on the first request.
        warm_ups = [executor.submit(_warm_up, self.task_fn) for _ in range(self.processes)]
        return _Generation(executor, threading.BoundedSemaphore(self.processes), warm_ups)

    def wait_ready(self, timeout_s: float) -> bool:
        """Wait until the workers have started and imported the task function."""
        with self._lock:
            generation = self._generation
        if generation is None:
            return False
        done, pending = wait(generation.warm_ups, timeout=timeout_s)
        return not pending and all(not f.cancelled() and f.exception() is None for f in done)

    def run(
        self, problem: PlanningProblem, timeout_s: float, meanwhile: Meanwhile | None = None
    ) -> PlanResult:
        """Run the task in a worker; ERROR on a crash, TIMEOUT or ERROR past `timeout_s`.

        `meanwhile` runs once the task has had `MEANWHILE_AFTER_S` to reach its worker (not
        before: it would hold the interpreter's lock that sending the task needs), unless the
        answer is back by then."""
        began = time.monotonic()
        deadline = began + timeout_s
        budget_ends = began + problem.budget_s  # a retry plans in what is left of the budget
        problem = replace(problem, model=self._spool.source(problem.model))
        retries = 0
        while (generation := self._claim_slot(deadline)) is not None:
            queued_s = time.monotonic() - began  # waiting for a free worker is not planning
            try:
                future = generation.executor.submit(self.task_fn, problem)
            except (BrokenProcessPool, RuntimeError) as exc:  # broken, or retired meanwhile
                generation.slots.release()
                self._replace(generation, crashed=isinstance(exc, BrokenProcessPool))
                continue
            with self._lock:
                generation.running[future] = deadline
            future.add_done_callback(lambda done: self._release(generation, done))
            if meanwhile is not None and not wait([future], timeout=MEANWHILE_AFTER_S).done:
                run_meanwhile(meanwhile)
            meanwhile = None  # once, even when a crash runs the task again
            try:
                result = future.result(timeout=max(0.0, deadline - time.monotonic()))
            except CancelledError:  # retired before it started: try the new executor
                continue
            except FutureTimeout:
                result = self._overran(generation, future, problem, timeout_s)
                if queued_s > timeout_s - problem.budget_s:  # it started too late for its budget
                    result.stats["queued_s"] = queued_s
                return _retried(result, retries)
            except BrokenProcessPool as exc:
                self._replace(generation, crashed=True)
                if retries < self.crash_retries:
                    # Planning starts once the new workers are up: that time is not planning time.
                    self.wait_ready(max(0.0, budget_ends - time.monotonic()))
                    left_s = budget_ends - time.monotonic()
                    if left_s >= MIN_RETRY_BUDGET_S:
                        retries += 1
                        problem = replace(problem, budget_s=left_s)
                        continue
                tried = f" {retries + 1} times" if retries else ""
                return error_result(
                    f"planning worker crashed{tried}; the pool was restarted", str(exc)
                )
            except Exception as exc:
                return error_result(f"planning task raised {type(exc).__name__}", repr(exc))
            if not isinstance(result, PlanResult):
                return error_result(f"planning task returned {type(result).__name__}")
            return _retried(result, retries)
        if self._generation is None:
            return error_result("planner pool is closed")
        return error_result(
            f"no planning worker became free within {timeout_s:g} s (all {self.processes} busy)"
        )

    def _claim_slot(self, deadline: float) -> _Generation | None:
        """The current generation with one of its slots taken; None when closed or too late."""
        while True:
            with self._lock:
                generation = self._generation
            remaining = deadline - time.monotonic()
            if generation is None or remaining <= 0:
                return None
            # Short waits, so that a waiter moves on to a new generation after a recycle.
            if generation.slots.acquire(timeout=min(remaining, 0.1)):
                return generation

    def _release(self, generation: _Generation, future: Future[PlanResult]) -> None:
        with self._lock:
            generation.running.pop(future, None)
        generation.slots.release()

    def _overran(
        self,
        generation: _Generation,
        future: Future[PlanResult],
        problem: PlanningProblem,
        timeout_s: float,
    ) -> PlanResult:
        watchdog = threading.Timer(
            self.overrun_grace_s, self._recycle_if_stuck, (generation, future)
        )
        watchdog.daemon = True
        watchdog.start()
        return PlanResult(
            PlannerStatus.TIMEOUT,
            message=f"planning overran its budget of "
            f"{problem.budget_s:g} s (no answer after {timeout_s:g} s); "
            "the worker may still be running",
        )

    def _recycle_if_stuck(self, generation: _Generation, future: Future[PlanResult]) -> None:
        if not future.done():
            self._replace(generation, crashed=False, stuck=future)

    def _replace(
        self, old: _Generation, *, crashed: bool, stuck: Future[PlanResult] | None = None
    ) -> None:
        """Swap in a new executor (once, whichever thread comes first) and retire the old one."""
        with self._lock:
            if self._generation is not old:
                return
            self._counts["crashes"] += int(crashed)
            self._counts["recycles"] += 1
            self._generation = self._new_generation()
        threading.Thread(target=self._retire, args=(old, stuck), daemon=True).start()

    def _retire(
        self, old: _Generation, stuck: Future[PlanResult] | None, *, patient: bool = True
    ) -> None:
        """Let the old executor's other requests finish (within their deadlines), then kill it."""
        # Private attribute, but the only handle on the workers; a stuck one must be killed.
        workers = list((getattr(old.executor, "_processes", None) or {}).values())
        if patient:
            old.executor.shutdown(wait=False, cancel_futures=True)
            with self._lock:
                others = {f: d for f, d in old.running.items() if f is not stuck}
            if others:
                wait(others, timeout=max(0.0, max(others.values()) - time.monotonic()))
        for process in workers:
            with contextlib.suppress(OSError, ValueError, AttributeError):  # already gone
                process.kill()
        if not patient:
            # Wait for the executor's thread to see its workers gone and end: then its queues,
            # and their semaphores, are released now, not reported leaked if this process is
            # then killed (as uvicorn's workers are by the SIGTERM they re-raise).
            old.executor.shutdown(wait=True, cancel_futures=True)

    def counters(self) -> dict[str, int]:
        """Crashes and recycles so far."""
        with self._lock:
            return dict(self._counts)

    def close(self) -> None:
        """Cancel queued work and stop the workers now."""
        with self._lock:
            old, self._generation = self._generation, None
        if old is not None:
            self._retire(old, None, patient=False)
        self._spool.close()


class _ModelSpool:
    """The models' mesh files, each model's pickled once into a private directory that the
    workers read (`ModelSource.files_at`), so that a task carries only their file name.

    A worker reads them only to build a model it has not built yet (`planning.run`). The
    directory (mode 0700) is this pool's own, and goes with it.
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


def _retried(result: PlanResult, retries: int) -> PlanResult:
    """`result`, marked with the number of crash retries it took (if any)."""
    if retries:
        result.stats["crash_retries"] = float(retries)
    return result
