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

from dataclasses import dataclass
from datetime import datetime, timedelta
from enum import Enum
from typing import Any, cast

import sqlalchemy as sa
from sqlalchemy.engine import CursorResult
from sqlalchemy.orm import Session, defer

from trajcache.db.models import SeedJob, SeedJobScene, utcnow
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.services.catalog.models import get_model
from trajcache.services.context import ServiceContext
from trajcache.services.errors import ConflictError, InvalidInputError, NotFoundError
from trajcache.services.seeding.spec import SeedJobSpec
from trajcache.services.seeding.work import expand

__all__ = [
    "ACTIVE",
    "JobState",
    "affected_rows",
    "cancel_job",
    "claim_job",
    "claimable_jobs",
    "create_job",
    "get_job",
    "list_jobs",
    "release_jobs",
]


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
    """Validate the whole job (422/413 naming what is wrong, 404 for the model), store it queued
    with its scenes (the 3D view shows what it seeds in them)."""
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
        stored=0,
        failed=0,
        errors=[],
    )
    session.add(row)
    session.flush()  # the job's id, for its scenes
    session.add_all(
        SeedJobScene(job_id=row.id, position=k, hash=scene.hash, payload=scene_to_payload(scene))
        for k, scene in enumerate(work.scenes)
    )
    session.commit()
    return row


@dataclass(frozen=True)
class SeedJobInfo:
    """A seed job's state and progress as returned by the API."""

    job_id: int
    name: str | None
    model_id: str
    state: str
    total: int
    done: int
    hits: int
    planned: int
    stored: int | None  # of the planned, newly stored (the rest were already stored)
    failed: int
    hit_rate: float | None
    eta_s: float | None  # seconds left, while running with an estimate
    runner: str | None
    lease_expires_at: datetime | None  # when the runner's claim runs out unless it renews it
    stale: bool  # running, but its claim ran out: its replica stopped without handing it back
    message: str | None
    errors: list[dict[str, Any]]
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    updated_at: datetime

    @classmethod
    def of(cls, row: SeedJob) -> SeedJobInfo:
        """The API view of a job row."""
        eta, now = None, utcnow()
        running = row.state == JobState.RUNNING.value
        if row.eta_at is not None and running:
            eta = round(max(0.0, (row.eta_at - now).total_seconds()), 1)
        lease_ends = row.lease_expires_at
        hit_rate = round(row.hits / row.done, 4) if row.done else None
        return cls(
            row.id,
            row.name,
            row.model_id,
            row.state,
            row.total,
            row.done,
            row.hits,
            row.planned,
            row.stored,
            row.failed,
            hit_rate,
            eta,
            row.lease_owner,
            lease_ends,
            running and lease_ends is not None and lease_ends < now,
            row.message,
            list(row.errors or []),
            row.created_at,
            row.started_at,
            row.finished_at,
            row.updated_at,
        )


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
    changed = release_jobs(
        session=session,
        where=sa.and_(SeedJob.id == job_id, SeedJob.state.in_(ACTIVE)),
        state=JobState.CANCELLED,
    )
    row = get_job(session=session, job_id=job_id)
    if changed == 0 and row.state != JobState.CANCELLED.value:
        raise ConflictError(f"seed job {job_id} is already {row.state}; it cannot be cancelled")
    return row


def release_jobs(
    *,
    session: Session,
    where: sa.ColumnElement[bool],
    state: JobState,
    values: dict[str, Any] | None = None,
) -> int:
    """Move the jobs `where` selects to `state` and clear their lease; how many rows changed.

    A finished state (not queued) also stamps `finished_at`; `values` are further columns
    (progress, message).
    """
    now = utcnow()
    finished = {} if state.value in ACTIVE else {"finished_at": now}
    result = session.execute(
        sa.update(SeedJob)
        .where(where)
        .values(
            **(values or {}),
            **finished,
            state=state.value,
            updated_at=now,
            lease_owner=None,
            lease_expires_at=None,
            eta_at=None,
        )
        .execution_options(synchronize_session=False)
    )
    session.commit()
    return affected_rows(result)


def _claimable(now: datetime) -> sa.ColumnElement[bool]:
    """Queued jobs and running ones whose lease ran out."""
    return sa.or_(
        SeedJob.state == JobState.QUEUED.value,
        sa.and_(
            SeedJob.state == JobState.RUNNING.value,
            sa.or_(SeedJob.lease_expires_at.is_(None), SeedJob.lease_expires_at < now),
        ),
    )


def claimable_jobs(*, session: Session, limit: int) -> list[int]:
    """Ids of queued jobs and of running jobs whose lease ran out, oldest first."""
    now = utcnow()
    rows = session.scalars(
        sa.select(SeedJob.id).where(_claimable(now)).order_by(SeedJob.id).limit(limit)
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
        .where(SeedJob.id == job_id, _claimable(now))
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
