"""Seed jobs over the API: a job's state and progress, pages of jobs, request examples."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

JobStateName = Literal["queued", "running", "completed", "cancelled", "failed"]
EXAMPLE_SPEC: dict[str, Any] = {
    "model_id": "5158592d7f5559c728b6d23f76857a89890f358d7aa40994d9e2338ac93ec821",
    "name": "door sweep",
    "workload": {
        "name": "door_sweep",
        "seed": 1,
        "doors_deg": {"start": 0, "stop": 90, "step": 10},
    },
}
EXAMPLE_VARIANTS: dict[str, Any] = {
    "model_id": "5158592d7f5559c728b6d23f76857a89890f358d7aa40994d9e2338ac93ec821",
    "base_scene": {"generator": "restroom", "seats_deg": 0},
    "sweep": {"param": "doors_deg", "start": 0, "stop": 90, "step": 10},
    "queries": [
        {
            "start": [1.0, 0.8, 1.57, 0, -0.5, 0, 0.5, 0, 1.0, 0],
            "goal": [1.0, 0.8, 1.57, 0.4, 0.2, 0, 1.2, 0, 1.0, 0],
        }
    ],
    "options": {"budget_s": 2.0},
}
SEED_JOB_EXAMPLES = {
    "door sweep workload": {"value": EXAMPLE_SPEC},
    "queries over door-angle variants": {"value": EXAMPLE_VARIANTS},
}


JOB_OUT: dict[str, Any] = {
    "job_id": 7,
    "name": "door sweep",
    "model_id": EXAMPLE_SPEC["model_id"],
    "state": "running",
    "total": 2710,
    "done": 1200,
    "hits": 1104,
    "planned": 94,
    "stored": 91,
    "failed": 2,
    "hit_rate": 0.92,
    "eta_s": 31.5,
    "runner": "api-1:4242:5f1c0e9a7b3d",
    "lease_expires_at": "2025-06-02T09:26:42.500214Z",
    "stale": False,
    "message": None,
    "errors": [
        {
            "index": 411,
            "label": "doors 10°, call 141: stall 2: stow → spray_rim",
            "reason": "failure: timeout: no path within 2 s",
        }
    ],
    "created_at": "2025-06-02T09:25:01.941173Z",
    "started_at": "2025-06-02T09:25:02.103311Z",
    "finished_at": None,
    "updated_at": "2025-06-02T09:26:12.500214Z",
}


class SeedJobError(BaseModel):
    """A work item that failed, and why."""

    index: int
    label: str
    reason: str


class SeedJobOut(BaseModel):
    """A seed job's state and progress (counters cover the first `done` items)."""

    model_config = ConfigDict(json_schema_extra={"examples": [JOB_OUT]})

    job_id: int
    name: str | None
    model_id: str
    state: JobStateName
    total: int
    done: int
    hits: int
    planned: int = Field(description="Items the planner answered (the cache could not).")
    stored: int | None = Field(
        description="Of the planned items, those whose path was newly stored; the others were "
        "identical to a trajectory already stored (null: a job created before this counter)."
    )
    failed: int
    hit_rate: float | None
    eta_s: float | None
    runner: str | None
    lease_expires_at: datetime | None = Field(
        description="When the runner's claim on the job runs out unless its next progress write "
        "renews it (null when no replica holds the job)."
    )
    stale: bool = Field(
        description="True while the job is `running` but its claim has run out: its replica "
        "stopped without handing it back (a crash). Another replica, or the restarted one, "
        "takes it over at its next look for jobs."
    )
    message: str | None
    errors: list[SeedJobError]
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    updated_at: datetime


class SeedJobPage(BaseModel):
    """A page of seed jobs, newest first."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [{"items": [JOB_OUT], "total": 1, "limit": 100, "offset": 0}]
        }
    )

    items: list[SeedJobOut]
    total: int
    limit: int
    offset: int
