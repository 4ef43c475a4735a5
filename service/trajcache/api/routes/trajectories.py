"""/v1/trajectories: store, list (filtered, paginated), read and delete cached trajectories."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Path, Query, Response

from trajcache.api.deps import CtxDep, PageDep, SessionDep
from trajcache.api.schemas import (
    SourceName,
    TrajectoryCreated,
    TrajectoryIn,
    TrajectoryOut,
    TrajectoryPage,
    TrajectorySummary,
)
from trajcache.services.models import get_model
from trajcache.services.trajectories import (
    delete_trajectory,
    get_trajectory,
    list_trajectories,
    store_trajectory,
    trajectory_states,
)

router = APIRouter(prefix="/trajectories", tags=["trajectories"])

TrajectoryId = Annotated[int, Path(ge=1, le=2**63 - 1, description="Trajectory id.")]
_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"description": "Unknown trajectory"}}


@router.post(
    "",
    status_code=201,
    response_model=TrajectoryCreated,
    summary="Store a trajectory (an identical one is not stored twice)",
    responses={
        200: {"description": "Already stored", "model": TrajectoryCreated},
        404: {"description": "Unknown model or robot"},
        409: {"description": "The robot is of another model"},
        413: {"description": "More states than max_trajectory_states"},
        422: {"description": "Wrong state length, NaN/Inf, out of joint limits"},
    },
)
def store_trajectory_route(
    body: TrajectoryIn, ctx: CtxDep, session: SessionDep, response: Response
) -> TrajectoryCreated:
    """201 with the new id, or 200 with the id of the identical stored trajectory."""
    model = get_model(session=session, registry=ctx.models, model_id=body.model_id)
    trajectory_id, created = store_trajectory(
        session=session,
        model=model,
        states=body.states,
        source=body.source,
        robot_id=body.robot_id,
        scene_hash=body.scene_hash,
        env=body.env,
        planning_time_ms=body.planning_time_ms,
        max_states=ctx.settings.max_trajectory_states,
        require_robot=True,
    )
    if not created:
        response.status_code = 200
    return TrajectoryCreated(trajectory_id=trajectory_id, created=created)


@router.get("", response_model=TrajectoryPage, summary="List trajectories (without states)")
def list_trajectories_route(
    session: SessionDep,
    page: PageDep,
    model_id: Annotated[str | None, Query(max_length=64)] = None,
    source: SourceName | None = None,
    robot_id: Annotated[str | None, Query(max_length=128)] = None,
) -> TrajectoryPage:
    """Trajectories by id, filtered by model, source and robot."""
    rows, total = list_trajectories(
        session=session,
        model_id=model_id,
        source=source,
        robot_id=robot_id,
        limit=page.limit,
        offset=page.offset,
    )
    items = [TrajectorySummary.model_validate(row) for row in rows]
    return TrajectoryPage(items=items, total=total, limit=page.limit, offset=page.offset)


@router.get(
    "/{trajectory_id}",
    response_model=TrajectoryOut,
    summary="A trajectory with its key states",
    responses=_NOT_FOUND,
)
def get_trajectory_route(trajectory_id: TrajectoryId, session: SessionDep) -> TrajectoryOut:
    """The trajectory `trajectory_id`."""
    row = get_trajectory(session=session, trajectory_id=trajectory_id)
    summary = TrajectorySummary.model_validate(row)
    return TrajectoryOut(**summary.model_dump(), states=trajectory_states(row))


@router.delete(
    "/{trajectory_id}",
    status_code=204,
    response_class=Response,
    summary="Delete a trajectory (replicas drop it on their next sync)",
    responses=_NOT_FOUND,
)
def delete_trajectory_route(trajectory_id: TrajectoryId, session: SessionDep) -> Response:
    """Delete `trajectory_id`."""
    delete_trajectory(session=session, trajectory_id=trajectory_id)
    return Response(status_code=204)
