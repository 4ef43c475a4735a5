"""Time in tests: a fake clock moved by hand, and waiting on a condition with a bounded deadline."""

from __future__ import annotations

import threading
from collections.abc import Callable

from trajcache.planning.deadline import Deadline

# A planning budget for problems a test needs solved: it never binds, even on a loaded machine
# (a search returns as soon as it is solved), so the verdict is the planner's, not the clock's.
NEVER_BINDS_S = 60.0
# App settings under which a request that does not name a budget plans with that one, too (the
# first miss also starts the app's worker within it).
SOLVABLE = {"plan_budget_s": NEVER_BINDS_S, "plan_budget_max_s": NEVER_BINDS_S}


class FakeClock:
    """A monotonic clock that moves only when told to (inject it where a `clock` is taken)."""

    def __init__(self, start: float = 0.0) -> None:
        self.now = start

    def __call__(self) -> float:
        return self.now

    def advance(self, seconds: float) -> None:
        """Move the clock forward."""
        self.now += seconds


def wait_until(
    condition: Callable[[], object], *, timeout_s: float = 10.0, interval_s: float = 0.01
) -> bool:
    """Poll `condition` every `interval_s` until it is true (True) or `timeout_s` passes
    (False)."""
    deadline = Deadline(timeout_s)
    idle = threading.Event()  # never set: waits without busy-looping
    while not condition():
        if deadline.expired():
            return bool(condition())
        idle.wait(min(interval_s, deadline.remaining()))
    return True


class CountingLock:
    """A lock that counts the acquisitions asked for, so a test can wait until threads queue."""

    def __init__(self) -> None:
        self.asked = 0
        self._count = threading.Lock()
        self._lock = threading.Lock()

    def __enter__(self) -> bool:
        with self._count:
            self.asked += 1
        return self._lock.acquire()

    def __exit__(self, *_exc: object) -> None:
        self._lock.release()
