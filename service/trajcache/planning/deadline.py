"""A time budget as an object (OMPL's PlannerTerminationCondition, reduced to what we need)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Deadline:
    """A point in time (monotonic clock) that planners must not run past."""

    budget_s: float
    started: float = field(default_factory=time.perf_counter)

    @property
    def ends(self) -> float:
        """The monotonic time at which the budget is spent."""
        return self.started + max(0.0, self.budget_s)

    def elapsed(self) -> float:
        """Seconds since the budget started."""
        return time.perf_counter() - self.started

    def remaining(self) -> float:
        """Seconds left, never negative."""
        return max(0.0, self.ends - time.perf_counter())

    def expired(self) -> bool:
        """True once the budget is spent."""
        return time.perf_counter() >= self.ends

    def sub(self, budget_s: float) -> Deadline:
        """A budget of at most `budget_s` from now that also ends no later than this one."""
        now = time.perf_counter()
        return Deadline(max(0.0, min(budget_s, self.ends - now)), started=now)
