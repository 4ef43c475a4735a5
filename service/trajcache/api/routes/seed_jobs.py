"""/v1/seed-jobs: pre-seed the cache from simulation; follow and cancel the jobs."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Path, Query, Request, Response
from pydantic import BaseModel, ConfigDict

from trajcache.api.bounded import BoundedBodyRoute
from trajcache.api.deps import CtxDep, PageDep, SessionDep
from trajcache.api.responses import COMMON, errors
from trajcache.db.models import SeedJob, utcnow
from trajcache.services.seed_spec import SeedJobSpec
from trajcache.services.seeding import cancel_job, create_job, get_job, list_jobs

router = APIRouter(
    prefix="/seed-jobs", tags=["seed jobs"], responses=COMMON, route_class=BoundedBodyRoute
)

JobId = Annotated[int, Path(ge=1, le=2**31 - 1, description="Seed job id.")]
JobStateName = Literal["queued", "running", "completed", "cancelled", "failed"]
_UNKNOWN_JOB = ("Unknown seed job", "seed job 7 not found")
_EXAMPLE_SPEC: dict[str, Any] = {
    "model_id": "5158592d7f5559c728b6d23f76857a89890f358d7aa40994d9e2338ac93ec821",
    "name": "door sweep",
    "workload": {
        "name": "door_sweep",
        "seed": 1,
        "doors_deg": {"start": 0, "stop": 90, "step": 10},
    },
}
_EXAMPLE_VARIANTS: dict[str, Any] = {
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
_EXAMPLES = {
    "door sweep workload": {"value": _EXAMPLE_SPEC},
    "queries over door-angle variants": {"value": _EXAMPLE_VARIANTS},
}


_JOB_OUT: dict[str, Any] = {
    "job_id": 7,
    "name": "door sweep",
    "model_id": _EXAMPLE_SPEC["model_id"],
    "state": "running",
    "total": 2710,
    "done": 1200,
    "hits": 1104,
    "planned": 94,
    "failed": 2,
    "hit_rate": 0.92,
    "eta_s": 31.5,
    "runner": "api-1:4242:5f1c0e9a7b3d",
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

    model_config = ConfigDict(json_schema_extra={"examples": [_JOB_OUT]})

    job_id: int
    name: str | None
    model_id: str
    state: JobStateName
    total: int
    done: int
    hits: int
    planned: int
    failed: int
    hit_rate: float | None
    eta_s: float | None
    runner: str | None
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
            "examples": [{"items": [_JOB_OUT], "total": 1, "limit": 100, "offset": 0}]
        }
    )

    items: list[SeedJobOut]
    total: int
    limit: int
    offset: int


def job_out(row: SeedJob) -> SeedJobOut:
    """The API view of a job row."""
    eta = None
    if row.eta_at is not None and row.state == "running":
        eta = round(max(0.0, (row.eta_at - utcnow()).total_seconds()), 1)
    return SeedJobOut(
        job_id=row.id,
        name=row.name,
        model_id=row.model_id,
        state=row.state,
        total=row.total,
        done=row.done,
        hits=row.hits,
        planned=row.planned,
        failed=row.failed,
        hit_rate=round(row.hits / row.done, 4) if row.done else None,
        eta_s=eta,
        runner=row.lease_owner,
        message=row.message,
        errors=[SeedJobError.model_validate(e) for e in (row.errors or [])],
        created_at=row.created_at,
        started_at=row.started_at,
        finished_at=row.finished_at,
        updated_at=row.updated_at,
    )


def _scheduler(request: Request) -> Any:
    background = getattr(request.app.state, "background", None)
    return None if background is None else background.seeds


@router.post(
    "",
    status_code=202,
    response_model=SeedJobOut,
    summary="Queue a seed job: plan scenes × queries (or a workload) and store the results as sim",
    response_description="Queued; follow it at the Location",
    description="Validates the whole job first (every scene, variant and query; sizes bounded "
    "by `seed_max_scenes` and `seed_max_queries`), then queues it; a replica runs it in the "
    "background through the plan flow, misses going to the worker pool (local or Celery). "
    "Trajectories the planner finds are stored with source `sim`, the scene hash and its "
    'environment values. Scenes: `scenes` (explicit or `{"generator": "restroom", ...}`), or '
    "`base_scene` with `variants` (scene patches, or generator parameters) or a `sweep` "
    '(`{"param": "doors_deg", "start": 0, "stop": 90, "step": 10}`). Queries: `queries` '
    "(start/goal, optionally one `scene` index each), or a `workload` (`cleaning` or "
    "`door_sweep` of the reference robot, each call in its own restroom state). A job survives "
    "restarts: an unfinished job resumes where its progress was last written.",
    openapi_extra={"requestBody": {"content": {"application/json": {"examples": _EXAMPLES}}}},
    responses=errors(
        {
            404: ("Unknown model", "robot model '5158592d' not found"),
            413: (
                "Body above max_body_bytes, or more scenes or requests than the settings allow",
                "the job has 120000 plan requests, more than seed_max_queries=100000",
            ),
            422: (
                "A scene, variant, query or option the job cannot use",
                "queries[3].goal is out of joint limits: joint2 = 2.5 not in [-2.059, 2.0944]",
            ),
        }
    ),
)
def create_job_route(
    body: SeedJobSpec, ctx: CtxDep, session: SessionDep, request: Request, response: Response
) -> SeedJobOut:
    """Validate and queue the job; this replica is told to look for it at once."""
    row = create_job(session=session, ctx=ctx, spec=body)
    scheduler = _scheduler(request)
    if scheduler is not None:
        scheduler.wake()
    response.headers["location"] = f"/v1/seed-jobs/{row.id}"
    return job_out(row)


@router.get(
    "",
    response_model=SeedJobPage,
    summary="List seed jobs (newest first)",
    description="Seed jobs, filtered by state and model, a page at a time.",
    responses=errors({422: ("Bad filter or page", "query.state: Input should be 'queued', …")}),
)
def list_jobs_route(
    session: SessionDep,
    page: PageDep,
    state: JobStateName | None = None,
    model_id: Annotated[str | None, Query(max_length=64)] = None,
) -> SeedJobPage:
    """A page of jobs."""
    rows, total = list_jobs(
        session=session, state=state, model_id=model_id, limit=page.limit, offset=page.offset
    )
    return SeedJobPage(
        items=[job_out(r) for r in rows], total=total, limit=page.limit, offset=page.offset
    )


@router.get(
    "/{job_id}",
    response_model=SeedJobOut,
    summary="A seed job's progress",
    description="State, done/total, hits, planned, failed (with the latest reasons), the hit "
    "rate so far and an estimate of the time left (`eta_s`, while running).",
    responses=errors({404: _UNKNOWN_JOB}),
)
def get_job_route(job_id: JobId, session: SessionDep) -> SeedJobOut:
    """The job `job_id`."""
    return job_out(get_job(session=session, job_id=job_id))


@router.delete(
    "/{job_id}",
    response_model=SeedJobOut,
    summary="Cancel a seed job",
    description="A queued or running job becomes `cancelled` at once; its runner stops "
    "submitting requests (at once on this replica, at its next progress write on another). "
    "Requests already in flight finish within their budget. Cancelling a cancelled job again "
    "is harmless; a finished job cannot be cancelled (409).",
    responses=errors(
        {404: _UNKNOWN_JOB, 409: ("Already finished", "seed job 7 is already completed")}
    ),
)
def cancel_job_route(job_id: JobId, session: SessionDep, request: Request) -> SeedJobOut:
    """Cancel the job and stop this replica's run of it."""
    row = cancel_job(session=session, job_id=job_id)
    scheduler = _scheduler(request)
    if scheduler is not None:
        scheduler.cancel(job_id)
    return job_out(row)
