"""Seed jobs: pre-seeding the cache from simulation, run in the background of the service.

A job plans a set of requests (`seed_spec`) through the robots' plan flow (`plan_in_scene`):
hits come from the cache, misses go to the worker pool (local or Celery, by configuration) and
what the planner finds is stored with source `sim`, the scene hash and environment values.

Lifecycle: `queued` → `running` → `completed` | `cancelled` | `failed` (the job could not run,
e.g. its model is gone). Everything is in the `seed_jobs` table, so any replica can answer for
any job and jobs survive restarts.

Only one replica runs a job: it must *claim* it first, one conditional UPDATE that succeeds for
a queued job or a running one whose lease ran out, and sets `lease_owner` (this replica) and
`lease_expires_at`. The runner renews the lease with every progress write (every
`seed_heartbeat_s`); a write that finds the job no longer leased to it (cancelled, or taken over
after a stall longer than `seed_lease_s`) stops the runner.

Restarts resume unfinished jobs. On a graceful shutdown the replica hands its jobs back
(`queued`, lease cleared) and any replica takes them at its next poll (at once on the
restarted one); after a crash the lease runs out and another replica, or the restarted one,
takes the job over within `seed_lease_s` + `seed_poll_interval_s`. Progress (`done` and the
counters) covers a finished prefix of the work items, so a resumed job starts at item `done`
and counts every item once; items after the prefix that finished before the stop are planned
again, and then hit the cache they filled.

`DELETE` cancels: the row becomes `cancelled` at once; the runner on this replica stops
submitting requests immediately, one on another replica at its next progress write. Requests
already in flight finish within their planning budget (what they find is still stored).
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import uuid
from datetime import timedelta
from enum import Enum
from typing import Any, cast

import sqlalchemy as sa
from sqlalchemy.engine import CursorResult
from sqlalchemy.orm import Session, defer

from trajcache.db.models import SeedJob, utcnow
from trajcache.services.context import ServiceContext
from trajcache.services.errors import ConflictError, InvalidInputError, NotFoundError
from trajcache.services.models import get_model
from trajcache.services.seed_spec import SeedJobSpec, expand

__all__ = [
    "ACTIVE",
    "JobState",
    "SeedScheduler",
    "cancel_job",
    "claim_job",
    "claimable_jobs",
    "create_job",
    "get_job",
    "list_jobs",
]

_log = logging.getLogger(__name__)


class JobState(str, Enum):
    """Where a seed job is in its life."""

    QUEUED = "queued"
    RUNNING = "running"
    COMPLETED = "completed"
    CANCELLED = "cancelled"
    FAILED = "failed"


ACTIVE = (JobState.QUEUED.value, JobState.RUNNING.value)


def affected_rows(result: Any) -> int:
    """How many rows an UPDATE or DELETE changed."""
    return int(cast(CursorResult[Any], result).rowcount)


def create_job(*, session: Session, ctx: ServiceContext, spec: SeedJobSpec) -> SeedJob:
    """Validate the whole job (422/413 naming what is wrong, 404 for the model), store it queued."""
    model = get_model(session=session, registry=ctx.models, model_id=spec.model_id)
    work = expand(spec, model=model, settings=ctx.settings)
    if not work.items:
        raise InvalidInputError("the job has no plan requests")
    row = SeedJob(
        name=spec.name,
        model_id=spec.model_id,
        state=JobState.QUEUED.value,
        spec=spec.model_dump(mode="json", exclude_none=True),
        total=len(work.items),
        done=0,
        hits=0,
        planned=0,
        failed=0,
        errors=[],
    )
    session.add(row)
    session.commit()
    return row


def get_job(*, session: Session, job_id: int) -> SeedJob:
    """The seed job `job_id`."""
    row = session.get(SeedJob, job_id, populate_existing=True)
    if row is None:
        raise NotFoundError(f"seed job {job_id} not found")
    return row


def list_jobs(
    *,
    session: Session,
    state: str | None = None,
    model_id: str | None = None,
    limit: int,
    offset: int = 0,
) -> tuple[list[SeedJob], int]:
    """A page of seed jobs, newest first, and the total matching count."""
    conditions = []
    if state is not None:
        conditions.append(SeedJob.state == state)
    if model_id is not None:
        conditions.append(SeedJob.model_id == model_id)
    total = session.execute(
        sa.select(sa.func.count()).select_from(SeedJob).where(*conditions)
    ).scalar_one()
    rows = session.scalars(
        sa.select(SeedJob)
        .options(defer(SeedJob.spec))
        .where(*conditions)
        .order_by(SeedJob.id.desc())
        .limit(limit)
        .offset(offset)
    ).all()
    return list(rows), int(total)


def cancel_job(*, session: Session, job_id: int) -> SeedJob:
    """Cancel a queued or running job (idempotent); a finished one is a ConflictError."""
    now = utcnow()
    changed = session.execute(
        sa.update(SeedJob)
        .where(SeedJob.id == job_id, SeedJob.state.in_(ACTIVE))
        .values(
            state=JobState.CANCELLED.value,
            finished_at=now,
            updated_at=now,
            lease_owner=None,
            lease_expires_at=None,
            eta_at=None,
        )
        .execution_options(synchronize_session=False)
    )
    session.commit()
    row = get_job(session=session, job_id=job_id)
    if affected_rows(changed) == 0 and row.state != JobState.CANCELLED.value:
        raise ConflictError(f"seed job {job_id} is already {row.state}; it cannot be cancelled")
    return row


def claimable_jobs(*, session: Session, limit: int) -> list[int]:
    """Ids of queued jobs and of running jobs whose lease ran out, oldest first."""
    now = utcnow()
    rows = session.scalars(
        sa.select(SeedJob.id)
        .where(
            sa.or_(
                SeedJob.state == JobState.QUEUED.value,
                sa.and_(
                    SeedJob.state == JobState.RUNNING.value,
                    sa.or_(SeedJob.lease_expires_at.is_(None), SeedJob.lease_expires_at < now),
                ),
            )
        )
        .order_by(SeedJob.id)
        .limit(limit)
    ).all()
    session.rollback()
    return [int(i) for i in rows]


def claim_job(*, session: Session, job_id: int, owner: str, lease_s: float) -> bool:
    """Take the job's lease for `owner` if nobody holds it; True when this call got it.

    One conditional UPDATE: concurrent claims of one job (on any replica) have one winner.
    """
    now = utcnow()
    claimed = session.execute(
        sa.update(SeedJob)
        .where(
            SeedJob.id == job_id,
            sa.or_(
                SeedJob.state == JobState.QUEUED.value,
                sa.and_(
                    SeedJob.state == JobState.RUNNING.value,
                    sa.or_(SeedJob.lease_expires_at.is_(None), SeedJob.lease_expires_at < now),
                ),
            ),
        )
        .values(
            state=JobState.RUNNING.value,
            lease_owner=owner,
            lease_expires_at=now + timedelta(seconds=lease_s),
            started_at=sa.func.coalesce(SeedJob.started_at, now),
            updated_at=now,
        )
        .execution_options(synchronize_session=False)
    )
    session.commit()
    return affected_rows(claimed) == 1


def replica_id() -> str:
    """A name for this scheduler that no other process (or restart) shares."""
    return f"{socket.gethostname()[:60]}:{os.getpid()}:{uuid.uuid4().hex[:12]}"


class SeedScheduler:
    """Claims queued and orphaned seed jobs for this replica and runs them in threads."""

    def __init__(self, ctx: ServiceContext) -> None:
        self.ctx = ctx
        self.owner = replica_id()
        self._runs: dict[int, Any] = {}  # job id -> JobRun
        self._lock = threading.Lock()
        self._poll_lock = threading.Lock()  # one poll at a time
        self._wake = threading.Event()
        self._stopping = threading.Event()
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
        from trajcache.services.seed_runner import JobRun

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

    def _loop(self) -> None:
        while not self._stopping.is_set():
            try:
                self.poll()
            except Exception as exc:  # the database may be away; try again at the next poll
                _log.warning("seed job poll failed: %s", exc)
            self._wake.wait(self.ctx.settings.seed_poll_interval_s)
            self._wake.clear()
