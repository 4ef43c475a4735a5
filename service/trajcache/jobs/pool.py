"""The planner pool: runs `PlanningProblem`s in worker processes (local) or Celery workers.

`PlannerPool.submit` is called concurrently from the web server's threads. On top of a backend it
adds request coalescing (identical in-flight queries plan once) and a negative cache (a query that
failed to plan in a scene is answered from memory for `negative_cache_ttl_s`).
"""

from __future__ import annotations

import contextlib
import importlib
import math
import multiprocessing
import signal
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Sequence
from concurrent.futures import CancelledError, Future, ProcessPoolExecutor, wait
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Protocol

from trajcache.core.config import Settings
from trajcache.jobs.threads import pin_one_thread
from trajcache.planning.problem import PlannerStatus, PlanningProblem, PlanResult

TaskFn = Callable[[PlanningProblem], PlanResult]
CoalescingKey = tuple[str, str, str, tuple[float, ...], tuple[float, ...]]

DEFAULT_TASK_FN = "trajcache.planning.run:run_planning"
OVERHEAD_S = 1.0  # allowance for scheduling and IPC on top of a request's planning budget
CRASH_RETRIES = 1  # runs again of a task whose local worker crashed (make_pool's choice)
MIN_RETRY_BUDGET_S = 0.1  # a crashed task is not run again with less budget left than this
NEGATIVE_CACHE_MAX_ENTRIES = 10_000
# Failures remembered by the negative cache; those of the first two hold for their budget only.
_BUDGETED = (PlannerStatus.TIMEOUT, PlannerStatus.UNCERTIFIED)
_NEGATIVE = (*_BUDGETED, PlannerStatus.INVALID_START, PlannerStatus.INVALID_GOAL)


def load_task_fn(path: str = DEFAULT_TASK_FN) -> TaskFn:
    """Import a task function named `module:function`."""
    module_name, _, attr = path.partition(":")
    if not module_name or not attr:
        raise ValueError(f"task function must be given as 'module:function', got {path!r}")
    fn: TaskFn = getattr(importlib.import_module(module_name), attr)
    return fn


def error_result(message: str) -> PlanResult:
    """A PlanResult for a planner that could not run."""
    return PlanResult(PlannerStatus.ERROR, message=message)


def coalescing_key(problem: PlanningProblem) -> CoalescingKey:
    """What makes two queries the same: model, scene, planner, start and goal to 1e-3."""
    return (
        problem.model.model_id,
        problem.scene.hash,
        problem.planner,
        _rounded(problem.start),
        _rounded(problem.goal),
    )


def _rounded(values: Sequence[float]) -> tuple[float, ...]:
    return tuple(round(v * 1e3) / 1e3 if math.isfinite(v) else v for v in map(float, values))


class PlanBackend(Protocol):
    """Where planning runs; `run` never raises and returns within `timeout_s` (plus IPC)."""

    def run(self, problem: PlanningProblem, timeout_s: float) -> PlanResult: ...

    def close(self) -> None: ...

    def counters(self) -> dict[str, int]: ...


@dataclass(frozen=True)
class PoolStats:
    """Counters of a planner pool since it started."""

    submitted: int  # submit() calls
    queue_depth: int  # planning runs submitted to the backend and not finished
    completed: int  # planning runs finished, whatever their status
    solved: int
    failures: int  # finished runs that did not solve (timeouts, invalid endpoints, errors)
    crashes: int  # worker processes that died mid-request
    recycles: int  # worker pools replaced (after a crash or an overrunning task)
    coalesced: int  # submissions answered by an identical in-flight run
    negative_hits: int  # submissions answered from the negative cache

    def as_dict(self) -> dict[str, int]:
        """The counters by name."""
        return asdict(self)


@dataclass(frozen=True)
class _Flight:
    future: Future[PlanResult]
    budget_s: float


@dataclass(frozen=True)
class _Failure:
    result: PlanResult
    budget_s: float
    at: float


class PlannerPool:
    """Runs planning problems on a backend, coalescing duplicates and remembering failures."""

    def __init__(
        self,
        backend: PlanBackend,
        *,
        negative_cache_ttl_s: float = 30.0,
        max_budget_s: float = math.inf,
        overhead_s: float = OVERHEAD_S,
    ) -> None:
        self.backend = backend
        self.negative_cache_ttl_s = negative_cache_ttl_s
        self.max_budget_s = max_budget_s
        self.overhead_s = overhead_s
        self._lock = threading.Lock()
        self._in_flight: dict[CoalescingKey, _Flight] = {}
        self._failures: dict[CoalescingKey, _Failure] = {}
        self._counts: Counter[str] = Counter()
        self._closed = False

    def submit(self, problem: PlanningProblem) -> PlanResult:
        """Plan `problem` and block until its result; never raises, never outlives the budget.

        Coalesced callers share one PlanResult object: treat it as read-only.
        """
        if problem.budget_s > self.max_budget_s:
            problem = replace(problem, budget_s=self.max_budget_s)
        key = coalescing_key(problem)
        answer, flight, leader = self._admit(key, problem.budget_s)
        if answer is not None:
            return answer
        if not leader:
            return self._wait(flight, problem.budget_s)
        result = error_result("planning was interrupted")
        try:
            result = self.backend.run(problem, problem.budget_s + self.overhead_s)
        except Exception as exc:  # a backend must not raise; keep the service up if one does
            result = error_result(f"planning backend failed: {exc!r}")
        finally:
            self._finish(key, flight, result)
        return result

    def _admit(
        self, key: CoalescingKey, budget_s: float
    ) -> tuple[PlanResult | None, _Flight, bool]:
        """An immediate answer, or the flight to lead or to wait for (and whether to lead)."""
        flight = _Flight(Future(), budget_s)
        with self._lock:
            self._counts["submitted"] += 1
            if self._closed:
                return error_result("planner pool is closed"), flight, False
            cached = self._negative_hit(key, budget_s)
            if cached is not None:
                self._counts["negative_hits"] += 1
                return cached, flight, False
            running = self._in_flight.get(key)
            if running is not None and running.budget_s >= budget_s:
                self._counts["coalesced"] += 1
                return None, running, False
            # A longer budget than the in-flight run's gets its own run (not registered).
            self._in_flight.setdefault(key, flight)
            self._counts["queue_depth"] += 1
            return None, flight, True

    def _wait(self, flight: _Flight, budget_s: float) -> PlanResult:
        try:
            return flight.future.result(timeout=budget_s + self.overhead_s)
        except FutureTimeout:
            return PlanResult(
                PlannerStatus.TIMEOUT,
                message="no answer within the budget "
                f"({budget_s:g} s) from an identical in-flight request",
            )

    def _finish(self, key: CoalescingKey, flight: _Flight, result: PlanResult) -> None:
        with self._lock:
            if self._in_flight.get(key) is flight:
                del self._in_flight[key]
            self._counts["queue_depth"] -= 1
            self._counts["completed"] += 1
            self._counts["solved" if result.status is PlannerStatus.SOLVED else "failures"] += 1
            # A failure of the budget after a crash retry, or of a task that waited in line for
            # a worker past the overhead allowance, had less than the flight's: not remembered.
            shortened = result.status in _BUDGETED and (
                result.stats.get("crash_retries") or result.stats.get("queued_s")
            )
            if result.status in _NEGATIVE and self.negative_cache_ttl_s > 0 and not shortened:
                self._remember_failure(key, _Failure(result, flight.budget_s, time.monotonic()))
        flight.future.set_result(result)

    def _remember_failure(self, key: CoalescingKey, failure: _Failure) -> None:
        self._failures.pop(key, None)
        if len(self._failures) >= NEGATIVE_CACHE_MAX_ENTRIES:
            horizon = failure.at - self.negative_cache_ttl_s
            self._failures = {k: f for k, f in self._failures.items() if f.at > horizon}
            while len(self._failures) >= NEGATIVE_CACHE_MAX_ENTRIES:
                del self._failures[next(iter(self._failures))]  # the oldest
        self._failures[key] = failure

    def _negative_hit(self, key: CoalescingKey, budget_s: float) -> PlanResult | None:
        failure = self._failures.get(key)
        if failure is None:
            return None
        age = time.monotonic() - failure.at
        if age >= self.negative_cache_ttl_s:
            del self._failures[key]
            return None
        # Running out of budget says nothing of a longer one; invalid endpoints hold for any.
        if failure.result.status in _BUDGETED and budget_s > failure.budget_s:
            return None
        message = (
            f"{failure.result.message} (negative cache: this query failed "
            f"{age:.1f} s ago in this scene; not replanned for "
            f"{self.negative_cache_ttl_s:g} s)"
        )
        return PlanResult(
            failure.result.status,
            message=message,
            stats={"negative_cache": 1.0},
            seed=failure.result.seed,  # the run whose failure is remembered
        )

    def stats(self) -> PoolStats:
        """A snapshot of the pool's counters."""
        with self._lock:
            counts = Counter(self._counts)
        counts.update(self.backend.counters())
        return PoolStats(**{f.name: counts[f.name] for f in fields(PoolStats)})

    def close(self) -> None:
        """Stop the backend; later submissions get an ERROR result."""
        with self._lock:
            self._closed = True
        self.backend.close()

    def __enter__(self) -> PlannerPool:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def _init_worker() -> None:
    """Runs first in every worker: Ctrl-C reaches the whole process group, but only the service
    decides when its workers stop (it stops them when it shuts down); and one numeric thread,
    as the workers share the machine's cores."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    pin_one_thread()


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

    def run(self, problem: PlanningProblem, timeout_s: float) -> PlanResult:
        """Run the task in a worker; ERROR on a crash, TIMEOUT or ERROR past `timeout_s`."""
        began = time.monotonic()
        deadline = began + timeout_s
        budget_ends = began + problem.budget_s  # a retry plans in what is left of the budget
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
                    f"planning worker crashed{tried} ({exc}); the pool was restarted"
                )
            except Exception as exc:
                return error_result(f"planning task raised {exc!r}")
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
        old.executor.shutdown(wait=False, cancel_futures=True)
        with self._lock:
            others = {f: d for f, d in old.running.items() if f is not stuck}
        if others and patient:
            wait(others, timeout=max(0.0, max(others.values()) - time.monotonic()))
        for process in workers:
            with contextlib.suppress(OSError, ValueError, AttributeError):  # already gone
                process.kill()

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


def _retried(result: PlanResult, retries: int) -> PlanResult:
    """`result`, marked with the number of crash retries it took (if any)."""
    if retries:
        result.stats["crash_retries"] = float(retries)
    return result


def make_pool(settings: Settings, *, task_fn: TaskFn | None = None) -> PlannerPool:
    """The planner pool chosen by `settings.worker_backend`."""
    backend: PlanBackend
    if settings.worker_backend == "celery":
        if task_fn is not None:
            raise ValueError("the celery backend runs the workers' task; task_fn is local-only")
        from trajcache.jobs.celery_app import CeleryBackend

        backend = CeleryBackend(settings, queue=settings.celery_queue)
    else:
        backend = LocalBackend(
            task_fn or load_task_fn(),
            processes=settings.worker_processes,
            crash_retries=CRASH_RETRIES,
        )
    return PlannerPool(
        backend,
        negative_cache_ttl_s=settings.negative_cache_ttl_s,
        max_budget_s=settings.plan_budget_max_s,
    )
