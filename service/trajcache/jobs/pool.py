"""The planner pool: runs `PlanningProblem`s in worker processes (local) or Celery workers.

`PlannerPool.submit` is called concurrently from the web server's threads. On top of a backend it
adds request coalescing (identical in-flight queries plan once) and a negative cache (a query that
failed to plan in a scene is answered from memory for `negative_cache_ttl_s`).
"""

from __future__ import annotations

import math
import threading
import time
from collections import Counter
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import asdict, dataclass, fields, replace

from trajcache.core.config import Settings
from trajcache.jobs.backend import (
    Meanwhile,
    PlanBackend,
    TaskFn,
    error_result,
    load_task_fn,
    run_meanwhile,
)
from trajcache.jobs.local import LocalBackend
from trajcache.planning.problem import PlannerStatus, PlanningProblem, PlanResult

CoalescingKey = tuple[str, str, str, tuple[float, ...], tuple[float, ...]]

OVERHEAD_S = 1.0  # allowance for scheduling and IPC on top of a request's planning budget
CRASH_RETRIES = 1  # runs again of a task whose local worker crashed (make_pool's choice)
NEGATIVE_CACHE_MAX_ENTRIES = 10_000
# Failures remembered by the negative cache; those of the first two hold for their budget only.
_BUDGETED = (PlannerStatus.TIMEOUT, PlannerStatus.UNCERTIFIED)
_NEGATIVE = (*_BUDGETED, PlannerStatus.INVALID_START, PlannerStatus.INVALID_GOAL)


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
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.backend = backend
        self.clock = clock  # ages the negative cache's entries
        self.negative_cache_ttl_s = negative_cache_ttl_s
        self.max_budget_s = max_budget_s
        self.overhead_s = overhead_s
        self._lock = threading.Lock()
        self._in_flight: dict[CoalescingKey, _Flight] = {}
        self._failures: dict[CoalescingKey, _Failure] = {}
        self._counts: Counter[str] = Counter()
        self._closed = False

    def submit(self, problem: PlanningProblem, *, meanwhile: Meanwhile | None = None) -> PlanResult:
        """Plan `problem` and block until its result; never raises, never outlives the budget.

        Coalesced callers share one PlanResult object: treat it as read-only. `meanwhile` is the
        caller's work to do while the problem plans elsewhere (`PlanBackend.run`); an answer
        known at once skips it.
        """
        if problem.budget_s > self.max_budget_s:
            problem = replace(problem, budget_s=self.max_budget_s)
        key = coalescing_key(problem)
        answer, flight, leader = self._admit(key, problem.budget_s)
        if answer is not None:
            return answer
        if not leader:
            run_meanwhile(meanwhile)
            return self._wait(flight, problem.budget_s)
        result = error_result("planning was interrupted")
        try:
            result = self.backend.run(problem, problem.budget_s + self.overhead_s, meanwhile)
        except Exception as exc:  # a backend must not raise; keep the service up if one does
            result = error_result("planning backend failed", repr(exc))
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
                self._remember_failure(key, _Failure(result, flight.budget_s, self.clock()))
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
        age = self.clock() - failure.at
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


def make_pool(settings: Settings, *, task_fn: TaskFn | None = None) -> PlannerPool:
    """The planner pool chosen by `settings.worker_backend`."""
    backend: PlanBackend
    if settings.worker_backend == "celery":
        if task_fn is not None:
            raise ValueError("the celery backend runs the workers' task; task_fn is local-only")
        from trajcache.jobs.celery_app import CeleryBackend  # celery loads only when chosen

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
