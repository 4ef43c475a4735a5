"""A planning task that tests can hold at its start, and the handle that holds it.

Worker processes import this module to run the task: it imports little besides the planner.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import replace
from pathlib import Path

from tests.waiting import wait_until
from trajcache.planning.deadline import Deadline
from trajcache.planning.problem import PlanningProblem, PlanResult
from trajcache.planning.run import run_planning

HELD_TASK = "tests.faults.held:held_planning"
HOLD_DIR = Path(tempfile.gettempdir()) / "trajcache-fault-holds"


def held_planning(problem: PlanningProblem) -> PlanResult:
    """`run_planning`, after announcing the attempt and waiting while its scene is held.

    A test holds a scene by creating `HOLD_DIR/<scene hash>`; each attempt in that scene then
    leaves `<scene hash>.<pid>.started` and waits until the hold is gone, so the test knows
    which worker process plans, and when. The wait uses up budget, as a slow start would.
    """
    hold = HOLD_DIR / problem.scene.hash
    if hold.exists():
        (HOLD_DIR / f"{problem.scene.hash}.{os.getpid()}.started").touch()
        deadline = Deadline(problem.budget_s)
        wait_until(lambda: not hold.exists(), timeout_s=problem.budget_s)
        problem = replace(problem, budget_s=max(0.01, deadline.remaining()))
    return run_planning(problem)


class Hold:
    """Holds the planning attempts in one scene (see `held_planning`)."""

    def __init__(self, scene_hash: str) -> None:
        self.scene_hash = scene_hash
        HOLD_DIR.mkdir(exist_ok=True)
        self._file = HOLD_DIR / scene_hash

    def hold(self) -> None:
        self._file.touch()

    def release(self) -> None:
        self._file.unlink(missing_ok=True)

    def attempts(self) -> list[int]:
        """Pids of the worker processes that started an attempt, oldest first."""
        started = sorted(
            HOLD_DIR.glob(f"{self.scene_hash}.*.started"), key=lambda p: p.stat().st_mtime_ns
        )
        return [int(p.name.split(".")[1]) for p in started]

    def wait_attempt(self, number: int, timeout: float = 20.0) -> int:
        """The pid of attempt `number` (1-based), once it has started."""
        started = wait_until(lambda: len(self.attempts()) >= number, timeout_s=timeout)
        assert started, f"planning attempt {number} did not start within {timeout:g} s"
        return self.attempts()[number - 1]

    def clear(self) -> None:
        self.release()
        for path in HOLD_DIR.glob(f"{self.scene_hash}.*.started"):
            path.unlink(missing_ok=True)
