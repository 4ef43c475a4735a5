"""The Celery backend of the planner pool: the app, the `trajcache.plan` task and its client.

Workers start with `celery -A trajcache.jobs.celery_app worker -Q plan` (or `trajcache worker`),
as any user. Tasks and results travel as JSON and workers accept nothing else
(`trajcache.jobs.wire`): a task names its model by id and its scene by hash, and a worker reads
those it lacks from the database, which it shares with the service (`trajcache.jobs.sources`).
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from concurrent.futures import Future, InvalidStateError, wait
from concurrent.futures import TimeoutError as FutureTimeout
from functools import lru_cache
from typing import Any

from celery import Celery
from celery.exceptions import TimeoutError as CeleryTimeout
from celery.result import AsyncResult
from celery.signals import worker_init, worker_process_init
from celery.utils.log import get_logger
from kombu.exceptions import EncodeError, OperationalError
from redis.exceptions import RedisError

from trajcache.core.config import Settings, get_settings
from trajcache.jobs.backend import (
    DEFAULT_TASK_FN,
    Meanwhile,
    TaskFn,
    error_result,
    load_task_fn,
    run_meanwhile,
)
from trajcache.jobs.sources import MissingSourceError, WorkerSources
from trajcache.jobs.threads import pin_one_thread
from trajcache.jobs.wire import (
    problem_from_message,
    result_from_message,
    result_message,
    task_message,
)
from trajcache.planning.problem import PlannerStatus, PlanningProblem, PlanResult
from trajcache.planning.warm import warm

PLAN_TASK = "trajcache.plan"
PLAN_QUEUE = "plan"
TASK_FN_ENV = "TRAJCACHE_CELERY_TASK_FN"  # `module:function` run by the plan task (tests, dev)
TIME_LIMIT_GRACE_S = 5.0  # a prefork worker kills a task this long after the caller gave up
CONNECT_TIMEOUT_S = 2.0
LIVENESS_CHECK_S = 0.5  # this long before its deadline, an unanswered request pings the worker

# Errors that say the broker or the result backend is out of reach (not that the task failed).
_UNAVAILABLE = (OperationalError, ConnectionError, OSError, RedisError)

logger = get_logger(__name__)


@lru_cache(maxsize=1)
def worker_task_fn() -> TaskFn:
    """The task function this worker process runs (run_planning unless overridden)."""
    return load_task_fn(os.environ.get(TASK_FN_ENV) or DEFAULT_TASK_FN)


@worker_init.connect(weak=False)
@worker_process_init.connect(weak=False)
def _one_numeric_thread(**_: object) -> None:
    """One numeric thread in the worker and in each of its pool's processes, before the task
    function's imports (connected first)."""
    pin_one_thread()


@worker_init.connect(weak=False)
def _warm_kernels(**_: object) -> None:
    """Compile, or load, the geometry kernels once in the worker, before it forks its pool's
    processes: they start with the kernels ready."""
    warm()


@worker_process_init.connect(weak=False)
def _import_task_fn(**_: object) -> None:
    """Import the task function when a worker process starts, not on its first request."""
    try:
        worker_task_fn()
    except Exception:  # reported by every task instead, as an ERROR result
        logger.exception("cannot import the planning task function")


@lru_cache(maxsize=1)
def worker_sources() -> WorkerSources:
    """The models and scenes this worker process has read from the database."""
    return WorkerSources(get_settings().database_url)


def plan(message: dict[str, Any]) -> dict[str, Any]:
    """The body of the `trajcache.plan` task: the same pure function as the local pool runs, on
    the problem the JSON message names."""
    sources = worker_sources()
    try:
        problem = problem_from_message(message, model_fn=sources.model, scene_fn=sources.scene)
    except MissingSourceError as exc:
        reason = f"{exc} in the worker's database (it needs the service's TRAJCACHE_DATABASE_URL)"
        return result_message(error_result(reason))
    return result_message(worker_task_fn()(problem))


def make_celery(settings: Settings, *, fail_fast: bool = False) -> Celery:
    """A Celery app for `settings`; `fail_fast` for clients that must not hang on a dead broker."""
    app = Celery(
        "trajcache",
        broker=settings.celery_broker_url,
        backend=settings.celery_result_backend,
        set_as_current=False,
    )
    app.conf.update(
        accept_content=["json"],  # nothing a worker would run code to decode
        result_accept_content=["json"],
        task_serializer="json",
        result_serializer="json",
        task_routes={PLAN_TASK: {"queue": PLAN_QUEUE}},
        task_track_started=True,  # lets a client tell "still queued" from "overran"
        task_acks_late=False,  # a task that crashed its worker is not redelivered to crash another
        worker_prefetch_multiplier=1,  # planning tasks are long: don't hoard them
        result_expires=600,
        broker_connection_timeout=CONNECT_TIMEOUT_S,
        broker_connection_retry_on_startup=True,
        redis_socket_connect_timeout=CONNECT_TIMEOUT_S,
        broker_transport_options={"socket_connect_timeout": CONNECT_TIMEOUT_S},
    )
    if fail_fast:  # a client answers ERROR at once; workers keep Celery's patient reconnects
        retry = {"max_retries": 1, "interval_start": 0, "interval_step": 0.2, "interval_max": 0.2}
        app.conf.update(
            task_publish_retry_policy=retry,
            broker_connection_max_retries=1,
            broker_pool_limit=None,  # no cap: a publisher never queues for a connection
            broker_transport_options={
                **retry,
                "socket_connect_timeout": CONNECT_TIMEOUT_S,
                "socket_timeout": CONNECT_TIMEOUT_S * 2,  # a hung Redis must not hang a publish
            },
            result_backend_transport_options={"retry_policy": {**retry, "timeout": 1.0}},
            redis_socket_timeout=10.0,
        )
    app.task(name=PLAN_TASK)(plan)
    return app


class CeleryBackend:
    """Sends problems to Celery workers and waits for their results."""

    def __init__(
        self,
        settings: Settings,
        *,
        queue: str = PLAN_QUEUE,
        app: Celery | None = None,
        time_limit_grace_s: float = TIME_LIMIT_GRACE_S,
    ) -> None:
        self.app = app or make_celery(settings, fail_fast=True)
        self.queue = queue
        self.time_limit_grace_s = time_limit_grace_s

    def run(
        self, problem: PlanningProblem, timeout_s: float, meanwhile: Meanwhile | None = None
    ) -> PlanResult:
        """Send the task and wait up to `timeout_s`; ERROR quickly when the broker is down.
        `meanwhile` runs once the task is sent."""
        deadline = time.monotonic() + timeout_s
        try:
            async_result = self.app.send_task(
                PLAN_TASK,
                args=(task_message(problem),),
                queue=self.queue,
                expires=timeout_s,  # not started by then: nobody waits for it any more
                time_limit=timeout_s + self.time_limit_grace_s,
            )
        except EncodeError as exc:
            return error_result("planning problem could not be serialized", _describe(exc))
        except Exception as exc:  # kombu's connection errors, redis errors, OSError
            return error_result("worker backend unavailable", _describe(exc))
        # AsyncResult.get checks its timeout only once a second: wait for it from a helper thread
        # so that this request's deadline holds to the millisecond.
        outcome: Future[object] = Future()
        threading.Thread(
            target=_collect,
            args=(async_result, timeout_s, outcome),
            name="trajcache-celery-result",
            daemon=True,
        ).start()
        run_meanwhile(meanwhile)
        check_at = deadline - min(LIVENESS_CHECK_S, max(0.0, timeout_s - problem.budget_s))
        if not wait([outcome], timeout=max(0.0, check_at - time.monotonic())).done:
            lost = self._lost_worker(async_result, outcome, deadline)
            if lost is not None:
                return error_result(
                    "a Celery worker stopped answering while it planned; the task was lost", lost
                )
        try:
            value = outcome.result(timeout=max(0.0, deadline - time.monotonic()))
        except (FutureTimeout, CeleryTimeout):
            return self._timed_out(async_result, problem, timeout_s)
        except Exception as exc:  # the task raised in the worker (or was revoked), or Redis left
            if isinstance(_cause(exc), _UNAVAILABLE):
                return error_result("worker backend unavailable", _describe(exc))
            return error_result("planning task failed in the worker", _describe(exc))
        if not isinstance(value, dict):
            return error_result(f"planning task returned {type(value).__name__}")
        try:
            return result_from_message(value)
        except (KeyError, TypeError, ValueError) as exc:
            return error_result("planning task returned a malformed result", _describe(exc))

    def _lost_worker(
        self, async_result: AsyncResult, outcome: Future[object], deadline: float
    ) -> str | None:
        """The worker that started the task, if it is gone (the task will never answer).

        A worker killed with its task (SIGKILL, out of memory, a lost machine) leaves the task
        STARTED forever: no one reports it. The worker that started it is pinged (prefork and
        thread pools answer while they plan; a `solo` worker cannot, so it looks lost).
        """
        try:
            state, info = async_result.state, async_result.info
        except Exception:  # the result backend is away: the timeout says what is known
            return None
        if state != "STARTED" or not isinstance(info, dict) or not info.get("hostname"):
            return None
        node = str(info["hostname"])
        answer: Future[bool] = Future()
        wait_s = max(0.05, deadline - time.monotonic())
        threading.Thread(
            target=_ping,
            args=(self.app, node, wait_s, answer),
            name="trajcache-celery-ping",
            daemon=True,
        ).start()
        try:
            if answer.result(timeout=wait_s) or outcome.done():
                return None
        except FutureTimeout:  # no reply in time
            if outcome.done():
                return None
        except Exception:  # the broker is away: cannot tell
            return None
        return f"worker {node!r}"

    def _timed_out(
        self, async_result: AsyncResult, problem: PlanningProblem, timeout_s: float
    ) -> PlanResult:
        try:
            state = async_result.state
        except Exception as exc:  # not known to have overrun: not a planning failure
            return error_result("worker backend unavailable", _describe(exc))
        if state == "PENDING":
            return error_result(
                f"no Celery worker started the planning task within "
                f"{timeout_s:g} s (queue {self.queue!r})"
            )
        return PlanResult(
            PlannerStatus.TIMEOUT,
            message=f"planning overran its budget of "
            f"{problem.budget_s:g} s (no answer after {timeout_s:g} s)",
        )

    def counters(self) -> dict[str, int]:
        """Celery workers keep their own counters."""
        return {}

    def close(self) -> None:
        """Release the broker and result backend connections."""
        self.app.close()


def _collect(async_result: AsyncResult, timeout_s: float, outcome: Future[object]) -> None:
    """Wait for a task's result into `outcome`, then drop it from the result backend."""
    try:
        outcome.set_result(async_result.get(timeout=timeout_s))
    except BaseException as exc:
        outcome.set_exception(exc)
    with contextlib.suppress(Exception):  # best effort: the result expires anyway
        async_result.forget()


def _ping(app: Celery, node: str, timeout_s: float, answer: Future[bool]) -> None:
    """Ping worker `node`: True into `answer` on its reply, False without one, or the error.

    The reply is passed on as it arrives: closing the reply channel afterwards takes a while.
    """

    def settle(value: bool | None = None, error: BaseException | None = None) -> None:
        with contextlib.suppress(InvalidStateError):  # settled already
            if error is not None:
                answer.set_exception(error)
            else:
                answer.set_result(bool(value))

    try:
        app.control.ping(
            destination=[node], timeout=timeout_s, limit=1, callback=lambda _: settle(True)
        )
    except Exception as exc:
        settle(error=exc)
    settle(False)


def _cause(exc: BaseException) -> BaseException:
    # Celery wraps a failed result-store reconnect in a RuntimeError: the cause is the error.
    if isinstance(exc, RuntimeError) and exc.__cause__ is not None:
        return exc.__cause__
    return exc


def _describe(exc: BaseException) -> str:
    exc = _cause(exc)
    return f"{type(exc).__name__}: {' '.join(str(exc).split())}"


celery_app = make_celery(get_settings())
app = celery_app  # `celery -A trajcache.jobs.celery_app` finds either name
