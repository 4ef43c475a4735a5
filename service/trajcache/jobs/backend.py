"""What a planner pool runs on: the backend protocol and the task function it runs.

Backends: `LocalBackend` (worker processes on this machine, `trajcache.jobs.local`) and
`CeleryBackend` (Celery workers, `trajcache.jobs.celery_app`).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Protocol

from trajcache.planning.problem import PlannerStatus, PlanningProblem, PlanResult

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


class PlanBackend(Protocol):
    """Where planning runs; `run` never raises and returns within `timeout_s` (plus IPC)."""

    def run(self, problem: PlanningProblem, timeout_s: float) -> PlanResult: ...

    def close(self) -> None: ...

    def counters(self) -> dict[str, int]: ...
