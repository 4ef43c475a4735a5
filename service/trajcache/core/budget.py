"""A share of one core that optional background work may take: measuring clearances for later
hits is worth doing, but never at the cost of the requests it would speed up."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

__all__ = ["WorkBudget"]


class WorkBudget:
    """At most `share` of wall time, over a sliding `window_s`, spent in `spend`; work that
    would exceed it is skipped (it is optional by contract)."""

    def __init__(
        self,
        share: float = 0.2,
        window_s: float = 2.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.share, self.window_s, self._clock = share, window_s, clock
        self._spent: list[tuple[float, float]] = []  # (ended at, seconds)
        self._lock = threading.Lock()
        self.skipped = 0  # work skipped for want of budget

    def spend(self, work: Callable[[], None]) -> bool:
        """Run `work` if the budget allows it now; whether it ran."""
        now = self._clock()
        with self._lock:
            self._spent = [(at, s) for at, s in self._spent if at > now - self.window_s]
            if sum(s for _, s in self._spent) >= self.share * self.window_s:
                self.skipped += 1
                return False
        began = self._clock()
        try:
            work()
        finally:
            ended = self._clock()
            with self._lock:
                self._spent.append((ended, ended - began))
        return True
