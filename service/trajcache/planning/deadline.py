"""A time budget as an object (OMPL's PlannerTerminationCondition, reduced to what we need)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Deadline:
    """A point in time on `clock` (monotonic seconds) that planners must not run past."""

    budget_s: float
    clock: Callable[[], float] = field(default=time.perf_counter, repr=False, compare=False)
    started: float = math.nan  # NaN: now on `clock`

    def __post_init__(self) -> None:
        if math.isnan(self.started):
            object.__setattr__(self, "started", self.clock())

    @property
    def ends(self) -> float:
        """The clock time at which the budget is spent."""
        return self.started + max(0.0, self.budget_s)

    def elapsed(self) -> float:
        """Seconds since the budget started."""
        return self.clock() - self.started

    def remaining(self) -> float:
        """Seconds left, never negative."""
        return max(0.0, self.ends - self.clock())

    def expired(self) -> bool:
        """True once the budget is spent."""
        return self.clock() >= self.ends

    def sub(self, budget_s: float) -> Deadline:
        """A budget of at most `budget_s` from now that also ends no later than this one."""
        now = self.clock()
        return Deadline(max(0.0, min(budget_s, self.ends - now)), clock=self.clock, started=now)
