"""/v1/trajectories: store, list (filtered, paginated), read and delete cached trajectories."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Query, Response

from trajcache.api.bounded import BoundedBodyRoute
from trajcache.api.deps import CtxDep, PageDep, SessionDep
from trajcache.api.responses import COMMON, errors
from trajcache.api.schemas.stats import PlanEventOut, TrajectoryDetailOut
from trajcache.api.schemas.trajectories import (
    SourceName,
    TrajectoryCreated,
    TrajectoryIn,
    TrajectoryPage,
    TrajectorySummary,
)
from trajcache.services.catalog.models import get_model
from trajcache.services.catalog.trajectories import (
    NewTrajectory,
    delete_trajectory,
    get_trajectory,
    list_trajectories,
    store_trajectory,
    trajectory_states,
)
from trajcache.services.stats.events import trajectory_usage

router = APIRouter(
    prefix="/trajectories", tags=["trajectories"], responses=COMMON, route_class=BoundedBodyRoute
)

TrajectoryId = Annotated[int, Path(ge=1, le=2**63 - 1, description="Trajectory id.")]
_BY_ID = errors(
    {
        404: ("Unknown trajectory", "trajectory 99 not found"),
        422: (
            "Not a trajectory id",
            "path.trajectory_id: Input should be greater than or equal to 1",
        ),
    }
)


@router.post(
    "",
    status_code=201,
    response_model=TrajectoryCreated,
    summary="Store a trajectory (an identical one is not stored twice)",
    response_description="Stored: a new trajectory",
    description="Contributes key states (straight lines in state space between them, ordered as "
    "the model's `state_names`) with their provenance (`real`, `sim`, `import`, `planner`) and "
    "the scene they were valid in. 201 with the new id; 200 with the stored id when an "
    "identical trajectory exists. Stored trajectories are validated again before every reuse.",
    responses={
        200: {"description": "Already stored", "model": TrajectoryCreated},
        **errors(
            {
                404: ("Unknown model or robot", "robot 'robot-7' not found"),
                409: (
                    "The robot is of another model",
                    "robot 'robot-7' is of model '5158592d', not of model '0c4e1a7f'",
                ),
                413: (
                    "More states than max_trajectory_states",
                    "trajectory has 6000 states, more than max_trajectory_states=5000",
                ),
                422: (
                    "Wrong state length, NaN/Inf, out of joint limits",
                    "state 1 (of 1 out of limits) is out of joint limits: j1 = 9 not in [-3, 3]",
                ),
            }
        ),
    },
)
def store_trajectory_route(
    body: TrajectoryIn, ctx: CtxDep, session: SessionDep, response: Response
) -> TrajectoryCreated:
    """201 with the new id, or 200 with the id of the identical stored trajectory."""
    model = get_model(session=session, registry=ctx.models, model_id=body.model_id)
    trajectory_id, created = store_trajectory(
        session=session,
        settings=ctx.settings,
        scenes=ctx.scenes,
        validators=ctx.validators,
        trajectory=NewTrajectory(
            model=model,
            states=body.states,
            source=body.source,
            robot_id=body.robot_id,
            scene_hash=body.scene_hash,
            env=body.env,
            planning_time_ms=body.planning_time_ms,
            max_states=ctx.settings.max_trajectory_states,
            require_robot=True,
        ),
    )
    if not created:
        response.status_code = 200
    return TrajectoryCreated(trajectory_id=trajectory_id, created=created)


@router.get(
    "",
    response_model=TrajectoryPage,
    summary="List trajectories (without states)",
    description="Stored trajectories by id, filtered by model, source and robot, a page at a time "
    "(`limit`, `offset`), with usage statistics (hits, validation failures, last use).",
    responses=errors(
        {
            422: ("Bad filter or page", "query.limit: 5000 is above max_page_size=1000"),
        }
    ),
)
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
    response_model=TrajectoryDetailOut,
    summary="A trajectory with its key states and usage history",
    description="The stored trajectory, its provenance and usage statistics, and its key states.",
    responses=_BY_ID,
)
def get_trajectory_route(trajectory_id: TrajectoryId, session: SessionDep) -> TrajectoryDetailOut:
    """The trajectory `trajectory_id` with its most recent plan events."""
    row = get_trajectory(session=session, trajectory_id=trajectory_id)
    summary = TrajectorySummary.model_validate(row)
    usage = trajectory_usage(session=session, trajectory_id=trajectory_id)
    return TrajectoryDetailOut(
        **summary.model_dump(),
        states=trajectory_states(row),
        usage_history=[PlanEventOut.model_validate(e) for e in usage],
    )


@router.delete(
    "/{trajectory_id}",
    status_code=204,
    response_class=Response,
    summary="Delete a trajectory (replicas drop it on their next sync)",
    response_description="Deleted",
    description="Deletes the trajectory; every replica stops serving it once it has synced "
    "with the database (before its next plan, by default).",
    responses=_BY_ID,
)
def delete_trajectory_route(trajectory_id: TrajectoryId, session: SessionDep) -> Response:
    """Delete `trajectory_id`."""
    delete_trajectory(session=session, trajectory_id=trajectory_id)
    return Response(status_code=204)
