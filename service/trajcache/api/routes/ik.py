"""POST /v1/robots/{robot_id}/ik: a state that puts a link at a pose, natively or as MoveIt's
GetPositionIK (a body with `ik_request`), answered by `services.ik.solve`."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Response

from trajcache.api.bounded import BoundedBodyRoute
from trajcache.api.deps import CtxDep, RobotIdPath
from trajcache.api.moveit import (
    GetPositionIKIn,
    GetPositionIKOut,
    MotionPlanError,
    RawBodyDep,
    answer_either,
    either_body,
    ik_answer_code,
    ik_query,
    ik_response,
)
from trajcache.api.responses import COMMON, errors
from trajcache.api.schemas.ik import IK_EXAMPLES, IkBody, IkResponse
from trajcache.services.ik.solve import IkAnswer, IkRequest, answer_ik
from trajcache.services.robot_model import robot_model_and_held

router = APIRouter(tags=["plan"], responses=COMMON, route_class=BoundedBodyRoute)

_NATIVE = {
    "link": "panda_hand",
    "position": [0.4, 0.1, 0.5],
    "orientation": [1.0, 0.0, 0.0, 0.0],
    "seed": [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
}
_MOVEIT = {
    "ik_request": {
        "group_name": "panda_arm",
        "ik_link_name": "panda_hand",
        "pose_stamped": {
            "header": {"frame_id": "panda_link0"},
            "pose": {"position": [0.4, 0.1, 0.5], "orientation": [1.0, 0.0, 0.0, 0.0]},
        },
        "avoid_collisions": True,
        "timeout": {"sec": 0, "nanosec": 50000000},
    }
}
_EXAMPLES = {
    "native": {"summary": "The native form", "value": _NATIVE},
    "moveit": {"summary": "MoveIt's GetPositionIK request", "value": _MOVEIT},
}
_MOVEIT_ANSWER = {
    "solution": {
        "joint_state": {
            "name": [f"panda_joint{k}" for k in range(1, 8)],
            "position": [0.02, -0.61, 0.01, -2.21, 0.0, 1.6, 0.8],
        },
        "multi_dof_joint_state": {"joint_names": [], "transforms": []},
    },
    "error_code": {"val": 1, "message": "", "source": "trajcache"},
    "trajcache": {
        "status": "success",
        "message": "",
        "warnings": ["group_name 'panda_arm' is ignored: the planning joints move"],
        "link": "panda_hand",
        "position_error": 0.0002,
        "orientation_error": 0.001,
        "timings_ms": {"db": 0.4, "solve": 1.2, "total": 1.8},
    },
}
_ANSWERS = {
    "native": {"summary": "The native answer", "value": IK_EXAMPLES[0]},
    "moveit": {"summary": "MoveIt's GetPositionIK response", "value": _MOVEIT_ANSWER},
}
_BODY = either_body(IkBody, GetPositionIKIn, _EXAMPLES, _MOVEIT)


@router.post(
    "/robots/{robot_id}/ik",
    response_model=IkResponse | GetPositionIKOut,
    summary="Inverse kinematics: a state that puts a link at a pose",
    description="Natively (`IkBody`): a link, a pose in the model's base frame (the world frame "
    "for a planar base), tolerances and an optional seed; the answer is the valid state nearest "
    "the seed among `solutions` found from the seed, cached trajectories' endpoints and random "
    "restarts, within the joint limits and, with `avoid_collisions` (default true), free of "
    "the robot's current scene and of self-collision. A planar base moves only with "
    "`move_base`. No solution is a 200 with status `not_found` or `in_collision`. As MoveIt's "
    "GetPositionIK (a body `{ik_request: ...}`, JSON or YAML): the answer is `{solution, "
    "error_code}` (1 success, -31 NO_IK_SOLUTION, -17 an unusable robot_state, -21 an unknown "
    "frame), `avoid_collisions` defaults to false as in MoveIt; see docs/moveit.md for the "
    "fields read and ignored. A 422 is for malformed input only.",
    openapi_extra=_BODY,
    responses={
        200: {"content": {"application/json": {"examples": _ANSWERS}}},
        **errors(
            {
                404: ("Unknown robot", "robot 'robot-7' not found"),
                422: (
                    "Malformed body, unknown link or a seed out of limits",
                    "link: 'hand' is neither a link nor an SRDF end effector of the model",
                ),
            }
        ),
    },
)
def ik_route(ctx: CtxDep, body: RawBodyDep, robot_id: RobotIdPath) -> Response:
    """Solve inverse kinematics for a robot in its current scene."""
    return answer_either(
        body,
        native=IkBody,
        native_fn=lambda native: _native_body(
            answer_ik(ctx=ctx, robot_id=robot_id, request=_request(native))
        ),
        moveit=GetPositionIKIn,
        moveit_keys=("ik_request",),
        moveit_fn=lambda message, began: _moveit(ctx, robot_id, message, began),
    )


def _request(body: IkBody) -> IkRequest:
    p, o = body.position, body.orientation
    return IkRequest(
        link=body.link,
        position=(p.x, p.y, p.z),
        orientation=(o.x, o.y, o.z, o.w),
        position_tolerance=body.position_tolerance,
        orientation_tolerance=body.orientation_tolerance,
        seed=body.seed,
        avoid_collisions=body.avoid_collisions,
        move_base=body.move_base,
        budget_s=body.budget_s,
        solutions=body.solutions,
    )


def _moveit(ctx: CtxDep, robot_id: str, message: GetPositionIKIn, began: float) -> dict[str, Any]:
    model, held = robot_model_and_held(ctx=ctx, robot_id=robot_id)
    try:
        query = ik_query(message, model=model, held=held)
    except MotionPlanError as exc:
        return ik_response(answer=None, query=None, code=exc.code, text=str(exc), began=began)
    answer = answer_ik(ctx=ctx, robot_id=robot_id, request=query.request)
    code = ik_answer_code(answer)
    return ik_response(answer=answer, query=query, code=code, text=answer.message, began=began)


def _native_body(answer: IkAnswer) -> dict[str, Any]:
    result = answer.result
    return {
        "status": answer.status.value,
        "state": None if answer.state is None else answer.state.tolist(),
        "state_names": list(answer.model.state_names),
        "link": answer.link,
        "position_error": result.position_error,
        "orientation_error": result.orientation_error,
        "solutions": result.solutions,
        "rejected": result.rejected,
        "attempts": result.attempts,
        "message": answer.message,
        "timings_ms": answer.timings_ms,
    }
