"""Typed answers of /v1/seed-jobs and /v1/admin: seed jobs, prunes and imports."""

from __future__ import annotations

from datetime import datetime
from typing import Literal

from trajcache_client._models import _Answer

SeedJobState = Literal["queued", "running", "completed", "cancelled", "failed"]
PrunePolicy = Literal["lru", "least_hit"]


class SeedJobError(_Answer):
    """A work item of a seed job that failed, and why."""

    index: int
    label: str
    reason: str


class SeedJob(_Answer):
    """A seed job's state and progress (the counters cover the first `done` items).

    `state` is one of `SeedJobState`; `eta_s` estimates the time left while it runs. `stale`
    says a `running` job's claim (`lease_expires_at`) ran out: its replica stopped without
    handing it back, and another one takes it over at its next look for jobs.
    """

    job_id: int
    name: str | None
    model_id: str
    state: SeedJobState | str
    total: int
    done: int
    hits: int
    planned: int
    stored: int | None = None  # of the planned, newly stored (the rest were already stored)
    failed: int
    hit_rate: float | None
    eta_s: float | None
    runner: str | None
    lease_expires_at: datetime | None
    stale: bool
    message: str | None
    errors: list[SeedJobError]
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    updated_at: datetime

    @property
    def active(self) -> bool:
        """True while the job is queued or running."""
        return self.state in ("queued", "running")


class ModelPrune(_Answer):
    """One model's prune: the trajectories it had, and the ids deleted (or to delete)."""

    model_id: str
    trajectories: int
    deleted: int
    ids: list[int]


class PruneResult(_Answer):
    """What a prune deleted, or would delete with `dry_run`."""

    dry_run: bool
    policy: PrunePolicy | str
    cap: int
    deleted: int
    models: list[ModelPrune]


class RejectedLine(_Answer):
    """A line of an import that was not imported, and why."""

    line: int
    reason: str


class ImportResult(_Answer):
    """What an import did (the first 1000 rejected lines are listed)."""

    lines: int
    models_created: int
    models_existing: int
    inserted: int
    duplicates: int
    cartesian_inserted: int
    cartesian_duplicates: int
    rejected_count: int
    rejected: list[RejectedLine]
