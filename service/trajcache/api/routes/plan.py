"""POST /v1/robots/{robot_id}/plan: parse, call the plan flow, map the answer."""

from __future__ import annotations

import time

import numpy as np
import pydantic_core
from fastapi import APIRouter, Response
from starlette.background import BackgroundTask

from trajcache.api.answer_extras import (
    answer_extras,
    extras_body,
)
from trajcache.api.bounded import BoundedBodyRoute
from trajcache.api.deps import CtxDep, RobotIdPath
from trajcache.api.responses import COMMON, errors
from trajcache.api.schemas.plan import GoalPoseIn, PlanBody, PlanResponse
from trajcache.geometry.model.kinematics import StateInput
from trajcache.services.plan.attempt import GoalPose
from trajcache.services.plan.flow import PlanAnswer, answer_plan
from trajcache.services.plan.options import PlanOptions as ServicePlanOptions

router = APIRouter(tags=["plan"], responses=COMMON, route_class=BoundedBodyRoute)


def _state(value: list[float] | dict[str, float] | str) -> StateInput:
    return np.asarray(value, dtype=float) if isinstance(value, list) else value


@router.post(
    "/robots/{robot_id}/plan",
    response_model=PlanResponse,
    summary="Plan from start to goal: a validated cached trajectory, or a fresh plan",
    description="Looks up cached trajectories whose start and goal are both near the request's "
    "(reversed ones included), adapts them to the exact start and goal, and validates them "
    "against the robot's current scene; when none is valid (and `options.fallback`), a planner "
    "runs in the worker pool within the time budget and what it finds is stored. States are "
    "ordered as the model's `state_names`. No path is an answer with status `miss`, `failure` "
    "or `error`, never an error status. A robot that never uploaded a scene is checked for "
    "self-collision only, which `warnings` says (an uploaded empty scene is no warning).",
    responses=errors(
        {
            404: ("Unknown robot", "robot 'robot-7' not found"),
            409: (
                "The robot never uploaded a scene and require_scene is on",
                "robot 'robot-7' has no scene: upload one (PUT /v1/robots/robot-7/scene, an "
                "empty one if its world is empty) before planning; require_scene is on",
            ),
            422: (
                "Bad state (length, NaN, limits) or start/goal in collision",
                "start state is in collision: link 'link5' hits object 'stall_2_door'",
            ),
        }
    ),
)
def plan_route(ctx: CtxDep, body: PlanBody, robot_id: RobotIdPath) -> Response:
    """Answer a plan request from the cache or the planner."""
    o = body.options
    answer = answer_plan(
        ctx=ctx,
        robot_id=robot_id,
        start=_state(body.start),
        goal=None if body.goal is None else _state(body.goal),
        goal_pose=_goal_pose(body.goal_pose),
        options=ServicePlanOptions(
            threshold=o.threshold,
            max_candidates=o.max_candidates,
            fallback=o.fallback,
            budget_s=o.budget_s,
            planner=o.planner,
            arm_only=o.match == "arm",
            lookup=o.lookup,
        ),
        extras=answer_extras(o.timing, o.quality),
    )
    # The answer is a PlanResponse by construction: serialized once, without a second validation.
    began = time.perf_counter()
    content = pydantic_core.to_json({**_response_body(answer), **extras_body(answer.details)})
    timings = {**answer.timings_ms, "serialize": (time.perf_counter() - began) * 1e3}
    # The request's cycle ends (after the response is sent) once its bookkeeping is written.
    background = None
    if answer.record is not None:
        background = BackgroundTask(ctx.records.written, answer.record)
    return Response(
        content,
        media_type="application/json",
        headers={"server-timing": ", ".join(f"{k};dur={v:.3f}" for k, v in timings.items())},
        background=background,
    )


def _goal_pose(pose: GoalPoseIn | None) -> GoalPose | None:
    if pose is None:
        return None
    x, y, z = pose.position
    qx, qy, qz, qw = pose.orientation
    return GoalPose(
        pose.link, (x, y, z), (qx, qy, qz, qw), pose.position_tolerance, pose.orientation_tolerance
    )


def _response_body(answer: PlanAnswer) -> dict[str, object]:
    """The fields of PlanResponse, from a plan answer."""
    return {
        "status": answer.status.value,
        "source": answer.source.value if answer.source else None,
        "trajectory_id": answer.trajectory_id,
        "states": answer.states.tolist() if answer.states is not None else None,
        "candidates_tried": answer.candidates_tried,
        "planner": answer.planner,
        "timings_ms": answer.timings_ms,
        "message": answer.message,
        "warnings": answer.warnings,
        "rejected": [
            {"trajectory_id": r["trajectory_id"], "status": r["status"], "reason": r["reason"]}
            for r in answer.rejected
        ],
        "validation": _validation(answer),
        "goal_state": None if answer.goal_state is None else answer.goal_state.tolist(),
        "goal_found_by": answer.goal_found_by,
    }


def _validation(answer: PlanAnswer) -> dict[str, object] | None:
    """What a cache answer's validation skipped (`ValidationReuse`)."""
    if answer.memo is None:
        return None
    use = answer.certificate
    return {
        "reused": answer.memo.value,
        "objects": use.objects if use is not None else None,
        "objects_reproved": use.reproved if use is not None else None,
        "objects_moved": use.moved if use is not None else None,
        "objects_clear": use.clear if use is not None else None,
        "ends_proved": answer.ends_proved,
    }
