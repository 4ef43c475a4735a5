"""POST /v1/robots/{robot_id}/motion-plan: MoveIt's MotionPlanRequest in, MotionPlanResponse out.

The request is translated to the native plan request and answered by the native plan flow
(`services.plan.flow.answer_request`), so it shares the cache, the validation and the bookkeeping of
POST /v1/robots/{robot_id}/plan; see `api.moveit` for the translation.
"""

from __future__ import annotations

import time
from typing import Any

import pydantic_core
import yaml
from fastapi import APIRouter, Request, Response
from starlette.background import BackgroundTask

from trajcache.api import refusals
from trajcache.api.answer_extras import answer_extras
from trajcache.api.bounded import BoundedBodyRoute
from trajcache.api.deps import CtxDep, RobotIdPath
from trajcache.api.moveit import (
    MotionPlanError,
    MotionPlanRequestIn,
    MotionPlanResponseOut,
    RawBodyDep,
    answered_body,
    inlined_schema,
    motion_plan_query,
    parse_motion_plan_request,
    refused_body,
    state_error_code,
)
from trajcache.api.responses import COMMON, errors
from trajcache.geometry.errors import StateError
from trajcache.services.errors import SceneRequiredError
from trajcache.services.plan.flow import answer_request
from trajcache.services.robot_model import robot_model_and_held

router = APIRouter(tags=["plan"], responses=COMMON, route_class=BoundedBodyRoute)

_YAML_EXAMPLE = """\
group_name: arm
start_state:
  joint_state:
    name: [shoulder, elbow]
    position: [0.0, 0.0]
goal_constraints:
  - joint_constraints:
      - {joint_name: shoulder, position: 1.0, tolerance_above: 0.01, tolerance_below: 0.01}
      - {joint_name: elbow, position: 0.5, tolerance_above: 0.01, tolerance_below: 0.01}
planner_id: RRTConnectkConfigDefault
allowed_planning_time: 1.0
max_velocity_scaling_factor: 0.5
max_acceleration_scaling_factor: 0.5
"""


_REQUEST_SCHEMA = inlined_schema(MotionPlanRequestIn)
_BODY: dict[str, Any] = {  # a YAML body is read into the same document as a JSON one
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": _REQUEST_SCHEMA},
            "application/yaml": {
                "schema": _REQUEST_SCHEMA,
                "example": yaml.safe_load(_YAML_EXAMPLE),
            },
        },
    }
}


@router.post(
    "/robots/{robot_id}/motion-plan",
    response_model=MotionPlanResponseOut,
    summary="Plan with MoveIt's messages: a MotionPlanRequest in, a MotionPlanResponse out",
    description="Takes a `moveit_msgs/MotionPlanRequest` as rosbridge-style JSON or YAML (bare, "
    "or wrapped as `motion_plan_request` or `request`) and answers it like `POST "
    "/v1/robots/{robot_id}/plan`, from the same cache: the start is `start_state` by joint "
    "name (a planar base: the first multi-DOF joint), the goal the first of "
    "`goal_constraints` whose joint constraints cover every planning joint, the budget "
    "`allowed_planning_time` (at most plan_budget_max_s), the planner `planner_id` (native or"
    " OMPL names; another id: the default planner). Start and goal positions just outside the"
    " joint limits are moved onto them as MoveIt does; what is read differently from MoveIt, "
    "or ignored, is listed in `warnings`. The answer is a `moveit_msgs/MotionPlanResponse` "
    "timed under the velocity and acceleration scaling factors, plus `trajcache` (cache or "
    "planner, timings). A well-formed request is answered 200 with MoveIt's error code: 1 "
    "success, -1 no path, -6 planner timeout, -10/-12 start/goal in collision, -16 unusable "
    "goal constraints (position/orientation goals included), -17 unusable start state, -22 no "
    "scene uploaded while require_scene is on (without it: a warning). Path "
    "and trajectory constraints, reference trajectories, Cartesian speed limits and attached "
    "objects are refused (422), never ignored.",
    openapi_extra=_BODY,
    responses=errors(
        {
            404: ("Unknown robot", "robot 'robot-7' not found"),
            413: (
                "Body above max_body_bytes",
                "request body has 17000000 bytes, more than max_body_bytes=16777216",
            ),
            415: (
                "Neither JSON nor YAML",
                "unsupported content type 'text/csv'; send application/json or application/yaml",
            ),
            422: (
                "Malformed body or an unsupported field",
                "body.path_constraints: Value error, path constraints are not supported: "
                "trajcache cannot honour them, so it refuses them",
            ),
        }
    ),
)
def motion_plan_route(
    ctx: CtxDep, body: RawBodyDep, robot_id: RobotIdPath, request: Request
) -> Response:
    """Answer a MoveIt motion plan request from the cache or the planner; a refusal (answered
    in-band) is recorded as the native endpoint's 4xx are (`api.refusals`)."""
    began = time.perf_counter()
    message = parse_motion_plan_request(body.media_type, body.data)
    model, held = robot_model_and_held(ctx=ctx, robot_id=robot_id)
    try:
        query = motion_plan_query(message, model=model, settings=ctx.settings, held=held)
    except MotionPlanError as exc:
        refused = refused_body(message=message, code=exc.code, text=str(exc), began=began)
        reason = f"MoveIt {exc.code.name} ({int(exc.code)}): {exc}"
        return _json(refused, refusals.record(ctx, request, reason))
    try:
        answer = answer_request(
            ctx=ctx,
            robot_id=robot_id,
            request=query.request,
            extras=answer_extras(query.timing, "basic"),
        )
    except (StateError, SceneRequiredError) as exc:  # the native endpoint's 422s and 409
        code = state_error_code(exc)
        refused = refused_body(
            message=message, code=code, text=str(exc), began=began, warnings=query.warnings
        )
        reason = f"MoveIt {code.name} ({int(code)}): {exc}"
        return _json(refused, refusals.record(ctx, request, reason))
    content = answered_body(message=message, query=query, model=model, answer=answer, began=began)
    # The request's cycle ends (after the response is sent) once its bookkeeping is written.
    background = None
    if answer.record is not None:
        background = BackgroundTask(ctx.records.written, answer.record)
    return _json(content, background)


def _json(content: dict[str, Any], background: BackgroundTask | None = None) -> Response:
    return Response(
        pydantic_core.to_json(content), media_type="application/json", background=background
    )
