"""The frame of a service process's maintenance threads: start, pause, run a step, stop.

A step that raises is logged and the loop goes on after a pause: the database may be away for
a while, and the next step tries again. `stop` waits for a step under way to finish, so a
write is never cut off in the middle of its transaction.
"""

from __future__ import annotations

import logging
import threading
from abc import ABC, abstractmethod
from typing import ClassVar, Self

from trajcache.services.context import ServiceContext

_log = logging.getLogger(__name__)


class BackgroundLoop(ABC):
    """A daemon thread that runs `step` after each pause until `stop`."""

    thread_name: ClassVar[str]
    step_name: ClassVar[str]  # what failed, in the warning a failed step logs

    def __init__(self, ctx: ServiceContext) -> None:
        self.ctx = ctx
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._loop, name=self.thread_name, daemon=True)

    def start(self) -> Self:
        """Start the thread; the first step comes after `first_pause_s`."""
        self._thread.start()
        return self

    def stop(self, timeout_s: float | None = None) -> None:
        """Stop the thread (a step under way finishes first)."""
        self._stopping.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    @abstractmethod
    def first_pause_s(self) -> float:
        """Seconds from the start to the first step."""

    @abstractmethod
    def step(self) -> float:
        """Do one round of the work; the seconds to wait before the next."""

    @abstractmethod
    def failure_pause_s(self) -> float:
        """Seconds to wait after a step that raised."""

    def _loop(self) -> None:
        pause = self.first_pause_s()
        while not self._stopping.wait(pause):
            try:
                pause = self.step()
            except Exception as exc:  # the database may be away; try again later
                _log.warning("%s failed: %s", self.step_name, exc)
                pause = self.failure_pause_s()
