"""The seed-job scheduler of one replica: it claims queued and orphaned jobs and runs them.

It polls every `seed_poll_interval_s` (and at once when woken: a job was queued, a run ended),
claims up to `seed_max_running_jobs` jobs (see `jobs` for the lease) and runs each in a
`JobRun`. On stop it hands its jobs back, so they resume on any replica. It also prunes old
seed jobs' scenes (`retention`), at start and then every `PRUNE_EVERY_S`.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
import uuid
from datetime import timedelta

from trajcache.services.context import ServiceContext
from trajcache.services.seeding.jobs import claim_job, claimable_jobs
from trajcache.services.seeding.retention import PRUNE_EVERY_S, prune_seed_scenes
from trajcache.services.seeding.runner import JobRun

__all__ = ["SeedScheduler", "replica_id"]

_log = logging.getLogger(__name__)


def replica_id() -> str:
    """A name for this scheduler that no other process (or restart) shares."""
    return f"{socket.gethostname()[:60]}:{os.getpid()}:{uuid.uuid4().hex[:12]}"


class SeedScheduler:
    """Claims queued and orphaned seed jobs for this replica and runs them in threads."""

    def __init__(self, ctx: ServiceContext) -> None:
        self.ctx = ctx
        self.owner = replica_id()
        self._runs: dict[int, JobRun] = {}
        self._lock = threading.Lock()
        self._poll_lock = threading.Lock()  # one poll at a time
        self._wake = threading.Event()
        self._stopping = threading.Event()
        self._next_prune = 0.0  # monotonic time of the next scene prune (0: at the first poll)
        self._thread = threading.Thread(target=self._loop, name="seed-scheduler", daemon=True)

    def start(self) -> SeedScheduler:
        """Start polling (the first poll is immediate: it resumes orphaned jobs)."""
        self._thread.start()
        return self

    def wake(self) -> None:
        """Poll now (a job was just queued, or a run ended)."""
        self._wake.set()

    def cancel(self, job_id: int) -> bool:
        """Stop this replica's run of `job_id` now, if it has one."""
        with self._lock:
            run = self._runs.get(job_id)
        if run is None:
            return False
        run.cancel()
        return True

    def running(self) -> list[int]:
        """Ids of the jobs this replica is running."""
        with self._lock:
            return sorted(self._runs)

    def poll(self) -> list[int]:
        """Claim and start jobs up to `seed_max_running_jobs`; the ids claimed."""
        with self._poll_lock:
            return self._claim_and_start()

    def _claim_and_start(self) -> list[int]:
        settings = self.ctx.settings
        claimed: list[int] = []
        with self._lock:
            free = settings.seed_max_running_jobs - len(self._runs)
            busy = set(self._runs)
        if free <= 0 or self._stopping.is_set():
            return claimed
        with self.ctx.sessions() as session:
            candidates = claimable_jobs(session=session, limit=free + len(busy) + 8)
            for job_id in candidates:
                if len(claimed) >= free or self._stopping.is_set():
                    break
                if job_id in busy:
                    continue
                if not claim_job(
                    session=session, job_id=job_id, owner=self.owner, lease_s=settings.seed_lease_s
                ):
                    continue
                run = JobRun(self.ctx, job_id, self.owner, on_exit=self._ended)
                with self._lock:
                    self._runs[job_id] = run
                run.start()
                claimed.append(job_id)
        return claimed

    def stop(self, timeout_s: float | None = None) -> None:
        """Stop polling and hand this replica's jobs back (they resume elsewhere or later)."""
        self._stopping.set()
        self._wake.set()
        if self._thread.is_alive():
            self._thread.join(timeout=timeout_s)
        with self._lock:
            runs = list(self._runs.values())
        for run in runs:
            run.shut_down()
        wait = timeout_s if timeout_s is not None else self.ctx.settings.plan_budget_max_s + 5.0
        for run in runs:
            run.join(wait)

    def _ended(self, job_id: int) -> None:
        with self._lock:
            self._runs.pop(job_id, None)
        self._wake.set()

    def prune_scenes(self) -> int:
        """Prune old seed jobs' scenes now (0 days of retention: never); how many went."""
        days = self.ctx.settings.seed_scene_retention_days
        if days <= 0:
            return 0
        with self.ctx.sessions() as session:
            return prune_seed_scenes(session, retention=timedelta(days=days))

    def _loop(self) -> None:
        while not self._stopping.is_set():
            try:
                self.poll()
                if time.monotonic() >= self._next_prune:
                    self._next_prune = time.monotonic() + PRUNE_EVERY_S
                    if pruned := self.prune_scenes():
                        _log.info("pruned %d scenes of old seed jobs", pruned)
            except Exception as exc:  # the database may be away; try again at the next poll
                _log.warning("seed job poll failed: %s", exc)
            self._wake.wait(self.ctx.settings.seed_poll_interval_s)
            self._wake.clear()
