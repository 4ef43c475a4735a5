"""/v1/seed-jobs: pre-seed the cache from simulation; follow and cancel the jobs."""

from __future__ import annotations

import dataclasses
from typing import Annotated, Any

from fastapi import APIRouter, Path, Query, Request, Response

from trajcache.api.bounded import BoundedBodyRoute
from trajcache.api.deps import CtxDep, PageDep, SessionDep
from trajcache.api.responses import COMMON, errors
from trajcache.api.schemas.seed_jobs import (
    SEED_JOB_EXAMPLES,
    JobStateName,
    SeedJobOut,
    SeedJobPage,
)
from trajcache.services.seeding.jobs import (
    SeedJobInfo,
    cancel_job,
    create_job,
    get_job,
    list_jobs,
)
from trajcache.services.seeding.spec import SeedJobSpec

router = APIRouter(
    prefix="/seed-jobs", tags=["seed jobs"], responses=COMMON, route_class=BoundedBodyRoute
)

JobId = Annotated[int, Path(ge=1, le=2**31 - 1, description="Seed job id.")]
_UNKNOWN_JOB = ("Unknown seed job", "seed job 7 not found")


def job_out(job: SeedJobInfo) -> SeedJobOut:
    """The API view of a job."""
    return SeedJobOut(**dataclasses.asdict(job))


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
    openapi_extra={
        "requestBody": {"content": {"application/json": {"examples": SEED_JOB_EXAMPLES}}}
    },
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
    return job_out(SeedJobInfo.of(row))


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
        items=[job_out(SeedJobInfo.of(r)) for r in rows],
        total=total,
        limit=page.limit,
        offset=page.offset,
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
    return job_out(SeedJobInfo.of(get_job(session=session, job_id=job_id)))


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
    return job_out(SeedJobInfo.of(row))
