"""POST /v1/robots/{robot_id}/cartesian-path: a link's straight lines through waypoints as a
certified joint path, natively or as MoveIt's GetCartesianPath, answered by
`services.cartesian.path`."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Response

from trajcache.api.answer_extras import answer_extras, extras_body
from trajcache.api.bounded import BoundedBodyRoute
from trajcache.api.deps import CtxDep, RobotIdPath
from trajcache.api.moveit import (
    GetCartesianPathIn,
    GetCartesianPathOut,
    MotionPlanError,
    RawBodyDep,
    answer_either,
    cartesian_query,
    cartesian_response,
    either_body,
)
from trajcache.api.responses import COMMON, errors
from trajcache.api.schemas.cartesian import (
    CARTESIAN_EXAMPLE,
    READY,
    CartesianBody,
    CartesianResponse,
)
from trajcache.services.cartesian.path import CartesianAnswer, CartesianRequest, answer_cartesian
from trajcache.services.cartesian.store import CacheQuery
from trajcache.services.robot_model import robot_model_and_held

router = APIRouter(tags=["plan"], responses=COMMON, route_class=BoundedBodyRoute)

MOVEIT_KEYS = ("start_state", "link_name", "group_name", "header")  # a GetCartesianPath body
_WAYPOINT = {"position": [0.307, 0.0, 0.49], "orientation": [1.0, 0.0, 0.0, 0.0]}
_NATIVE = {"start": READY, "link": "panda_hand", "waypoints": [_WAYPOINT], "max_step": 0.01}
_MOVEIT = {
    "header": {"frame_id": "panda_link0"},
    "start_state": {
        "joint_state": {"name": [f"panda_joint{k}" for k in range(1, 8)], "position": READY}
    },
    "group_name": "panda_arm",
    "link_name": "panda_hand",
    "waypoints": [_WAYPOINT],
    "max_step": 0.01,
    "jump_threshold": 0.0,
    "avoid_collisions": True,
}
_EXAMPLES = {
    "native": {"summary": "The native form", "value": _NATIVE},
    "moveit": {"summary": "MoveIt's GetCartesianPath request", "value": _MOVEIT},
}
_BODY = either_body(CartesianBody, GetCartesianPathIn, _EXAMPLES, _MOVEIT)
_ANSWERS = {"native": {"summary": "The native answer", "value": CARTESIAN_EXAMPLE}}


@router.post(
    "/robots/{robot_id}/cartesian-path",
    response_model=CartesianResponse | GetCartesianPathOut,
    summary="A Cartesian path: a link along straight lines through waypoints",
    description="Natively (`CartesianBody`): from the link's pose at `start`, straight lines "
    "(position linear, orientation slerp) through `waypoints` (the frame IK reads), sampled "
    "every `max_step` m and `max_rotation_step` rad, each sample solved by IK warm-started from "
    "the previous one. The path stops at the first sample without an IK solution, over a jump "
    "threshold, or whose joint motion fails certified validation in the robot's current scene "
    "(always: `avoid_collisions` false is not honoured, and says so). `fraction` is MoveIt's; "
    "`max_deviation_m` bounds the link's distance from its lines between states. A repeat "
    "within the `cache` tolerances is served from the cache, certified in the current scene. "
    "As MoveIt's GetCartesianPath (a body with `start_state`, `link_name`, `waypoints`, ...; "
    "JSON or YAML): the answer is `{start_state, solution, fraction, error_code}`, SUCCESS "
    "with any fraction; `path_constraints` and `max_cartesian_speed` are refused (422). See "
    "docs/moveit.md. A 422 is for malformed input only.",
    openapi_extra=_BODY,
    responses={
        200: {"content": {"application/json": {"examples": _ANSWERS}}},
        **errors(
            {
                404: ("Unknown robot", "robot 'robot-7' not found"),
                422: (
                    "Malformed body, unknown link, a start out of limits, or a field refused",
                    "path_constraints: path constraints are not supported: trajcache cannot "
                    "honour them, so it refuses them",
                ),
            }
        ),
    },
)
def cartesian_route(ctx: CtxDep, body: RawBodyDep, robot_id: RobotIdPath) -> Response:
    """Compute (or serve from the cache) a Cartesian path for a robot in its current scene."""
    return answer_either(
        body,
        native=CartesianBody,
        native_fn=lambda native: _native_body(
            answer_cartesian(ctx=ctx, robot_id=robot_id, request=_request(native))
        ),
        moveit=GetCartesianPathIn,
        moveit_keys=MOVEIT_KEYS,
        moveit_fn=lambda message, began: _moveit(ctx, robot_id, message, began),
    )


def _request(body: CartesianBody) -> CartesianRequest:
    extras = answer_extras(body.timing, "basic")
    return CartesianRequest(
        start=body.start,
        waypoints=tuple(
            ((w.position.x, w.position.y, w.position.z), (o.x, o.y, o.z, o.w))
            for w, o in ((w, w.orientation) for w in body.waypoints)
        ),
        link=body.link,
        max_step=body.max_step,
        max_rotation_step=body.max_rotation_step,
        jump_threshold=body.jump_threshold,
        revolute_jump_threshold=body.revolute_jump_threshold,
        prismatic_jump_threshold=body.prismatic_jump_threshold,
        position_tolerance=body.position_tolerance,
        orientation_tolerance=body.orientation_tolerance,
        avoid_collisions=body.avoid_collisions,
        timing=extras.timing,
        cache=CacheQuery(
            lookup=body.cache.lookup,
            store=body.cache.store,
            joint_tolerance=body.cache.joint_tolerance,
            position_tolerance=body.cache.position_tolerance,
            orientation_tolerance=body.cache.orientation_tolerance,
        ),
    )


def _moveit(
    ctx: CtxDep, robot_id: str, message: GetCartesianPathIn, began: float
) -> dict[str, Any]:
    model, held = robot_model_and_held(ctx=ctx, robot_id=robot_id)
    try:
        query = cartesian_query(message, model=model, held=held)
    except MotionPlanError as exc:
        return cartesian_response(answer=None, query=None, error=exc, began=began)
    answer = answer_cartesian(ctx=ctx, robot_id=robot_id, request=query.request)
    return cartesian_response(answer=answer, query=query, error=None, began=began)


def _native_body(answer: CartesianAnswer) -> dict[str, Any]:
    return {
        "status": answer.status.value,
        "source": answer.source,
        "fraction": answer.fraction,
        "states": answer.states.tolist(),
        "state_names": list(answer.model.state_names),
        "link": answer.link,
        "max_deviation_m": answer.max_deviation_m,
        "message": answer.message,
        "warnings": answer.warnings,
        "path_id": answer.path_id,
        **extras_body(answer.details),
        "timings_ms": answer.timings_ms,
    }
