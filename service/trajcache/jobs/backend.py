"""What a planner pool runs on: the backend protocol and the task function it runs.

Backends: `LocalBackend` (worker processes on this machine, `trajcache.jobs.local`) and
`CeleryBackend` (Celery workers, `trajcache.jobs.celery_app`).
"""

from __future__ import annotations

import importlib
import logging
from collections.abc import Callable
from typing import Protocol

from trajcache.planning.problem import PlannerStatus, PlanningProblem, PlanResult

logger = logging.getLogger(__name__)

TaskFn = Callable[[PlanningProblem], PlanResult]

DEFAULT_TASK_FN = "trajcache.planning.run:run_planning"


def load_task_fn(path: str = DEFAULT_TASK_FN) -> TaskFn:
    """Import a task function named `module:function`."""
    module_name, _, attr = path.partition(":")
    if not module_name or not attr:
        raise ValueError(f"task function must be given as 'module:function', got {path!r}")
    fn: TaskFn = getattr(importlib.import_module(module_name), attr)
    return fn


def error_result(message: str, detail: str = "") -> PlanResult:
    """A PlanResult for a planner that could not run: `message` for the robot that asked,
    `detail` (exception text, hosts) for the plan event and the log only."""
    return PlanResult(PlannerStatus.ERROR, message=message, detail=detail)


# Work of the caller's to do while a worker plans (`PlannerPool.submit`); its errors are logged.
Meanwhile = Callable[[], object]


def run_meanwhile(meanwhile: Meanwhile | None) -> None:
    """Run the caller's work while the task plans elsewhere; an error in it is logged, never
    raised: the planning it waits for goes on."""
    if meanwhile is None:
        return
    try:
        meanwhile()
    except Exception:
        logger.warning("work done while planning failed", exc_info=True)


class PlanBackend(Protocol):
    """Where planning runs; `run` never raises and returns within `timeout_s` (plus IPC). Once
    the task has left for its worker, `run` does `meanwhile` (if the answer is not back yet)."""

    def run(
        self, problem: PlanningProblem, timeout_s: float, meanwhile: Meanwhile | None = None
    ) -> PlanResult: ...

    def close(self) -> None: ...

    def counters(self) -> dict[str, int]: ...
