"""MoveIt's `GetCartesianPath` over HTTP: its request in, `{start_state, solution, fraction,
error_code}` out, answered by the native Cartesian path (`services.cartesian.path`).

Read: `start_state` (as a plan's, bounds fixed as MoveIt fixes a start's), `link_name` (empty:
the model's end-effector link; an SRDF end effector: its parent link), `waypoints` in
`header.frame_id` (as IK reads a pose: the world, or the root link), `max_step` (m, > 0),
`jump_threshold` (relative, as MoveIt), `revolute_jump_threshold` and
`prismatic_jump_threshold` (absolute), `max_velocity_scaling_factor` and
`max_acceleration_scaling_factor` (the timing's; 0: 1.0). `avoid_collisions` is always read as
true (false: a warning says it is not honoured). Ignored, with a warning: `group_name` (the
planning joints move) and `cartesian_speed_limited_link` without a speed. Refused (422):
non-empty `path_constraints`, `max_cartesian_speed` > 0, `max_step` ≤ 0. The rotation step,
the IK tolerances and the cache tolerances are the native defaults. `error_code` is SUCCESS
whenever a path was computed, whatever its `fraction` (as MoveIt).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field

from trajcache.api.answer_extras import extras_body
from trajcache.api.moveit._codes import MotionPlanError, MoveItErrorCode
from trajcache.api.moveit._ik import DEFAULT_BASE_JOINT, PoseStamped, pose_in_base_frame
from trajcache.api.moveit._messages import (
    Constraints,
    Finite,
    Name,
    NoCartesianSpeed,
    NoPathConstraints,
    Pose,
    RobotState,
    _Message,
)
from trajcache.api.moveit._request import read_start_state
from trajcache.api.moveit._response import robot_state_body, robot_trajectory_body
from trajcache.api.moveit._schemas import ErrorCodeOut, RobotStateOut, RobotTrajectoryOut
from trajcache.api.moveit._state import held_targets
from trajcache.geometry.model.robot import RobotModel
from trajcache.services.cartesian.path import CartesianAnswer, CartesianRequest
from trajcache.services.quality import TimingRequest

SAMPLE_PERIOD_S = 0.01  # the answer's points, as the MoveIt plan form samples them
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Scaling = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]


class GetCartesianPathIn(_Message):
    """A `moveit_msgs/GetCartesianPath` request (ROS 1 or 2, with MoveIt 2's speed fields)."""

    header: dict[str, Any] = Field(default_factory=dict)
    start_state: RobotState = Field(default_factory=RobotState)
    group_name: Name = Field(default="", description="Ignored: the planning joints move.")
    link_name: Name = ""
    waypoints: Annotated[list[Pose], Field(min_length=1, max_length=256)]
    max_step: Finite = Field(gt=0, description="Largest step of the link's origin (m), > 0.")
    jump_threshold: NonNegative = 0.0
    prismatic_jump_threshold: NonNegative = 0.0
    revolute_jump_threshold: NonNegative = 0.0
    avoid_collisions: bool = Field(
        default=False, description="Read as true: every motion is certified collision-free."
    )
    path_constraints: NoPathConstraints = Field(default_factory=Constraints)
    max_velocity_scaling_factor: Scaling = 0.0
    max_acceleration_scaling_factor: Scaling = 0.0
    cartesian_speed_limited_link: Name = ""
    max_cartesian_speed: NoCartesianSpeed = 0.0


class TrajcacheCartesianOut(BaseModel):
    """How the native Cartesian path answered, for operators (not part of MoveIt's message)."""

    status: Literal[
        "complete",
        "no_ik_solution",
        "joint_jump",
        "collision",
        "too_close",
        "out_of_limits",
        "invalid",
    ] = Field(description="Why the path stopped; 'invalid': refused before computing.")
    source: Literal["computed", "cache"] | None
    message: str
    warnings: list[str] = Field(description="What of the request was ignored or read otherwise.")
    link: str | None = Field(description="The link moved.")
    max_deviation_m: float | None = Field(
        description="Bound on the link's distance from its lines between the path's states."
    )
    path_id: int | None
    timings_ms: dict[str, float]


class GetCartesianPathOut(BaseModel):
    """A `moveit_msgs/GetCartesianPath` response, plus `trajcache`: how it was answered."""

    start_state: RobotStateOut
    solution: RobotTrajectoryOut
    fraction: float
    error_code: ErrorCodeOut
    trajcache: TrajcacheCartesianOut


@dataclass(frozen=True)
class CartesianQuery:
    """A GetCartesianPath request in native terms."""

    request: CartesianRequest
    base_joint: str
    warnings: tuple[str, ...]


def cartesian_query(
    message: GetCartesianPathIn, *, model: RobotModel, held: Mapping[str, float]
) -> CartesianQuery:
    """The native request of `message`; MotionPlanError with MoveIt's code when unusable."""
    warnings: list[str] = []
    start = read_start_state(message.start_state, model, held_targets(model, held), warnings)
    waypoints = tuple(
        pose_in_base_frame(
            PoseStamped(header=message.header, pose=pose),
            model,
            start,
            ("header.frame_id", f"waypoints[{k}].orientation"),
        )
        for k, pose in enumerate(message.waypoints)
    )
    if message.group_name:
        warnings.append(f"group_name {message.group_name!r} is ignored: the planning joints move")
    if message.cartesian_speed_limited_link:
        warnings.append("cartesian_speed_limited_link is ignored: no max_cartesian_speed is set")
    timing = TimingRequest(
        velocity_scaling=message.max_velocity_scaling_factor or 1.0,
        acceleration_scaling=message.max_acceleration_scaling_factor or 1.0,
        sample_period_s=SAMPLE_PERIOD_S,
    )
    request = CartesianRequest(
        start=list(map(float, start)),
        waypoints=waypoints,
        link=message.link_name,
        max_step=message.max_step,
        jump_threshold=message.jump_threshold,
        revolute_jump_threshold=message.revolute_jump_threshold,
        prismatic_jump_threshold=message.prismatic_jump_threshold,
        avoid_collisions=message.avoid_collisions,
        timing=timing,
        names={"link": "link_name", "start": "start_state", "waypoints": "waypoints"},
    )
    multi_dof = message.start_state.multi_dof_joint_state.joint_names
    return CartesianQuery(
        request, multi_dof[0] if multi_dof else DEFAULT_BASE_JOINT, tuple(warnings)
    )


def cartesian_response(
    *,
    answer: CartesianAnswer | None,
    query: CartesianQuery | None,
    error: MotionPlanError | None,
    began: float,
) -> dict[str, Any]:
    """The GetCartesianPath response (SUCCESS with any fraction; an unusable request's code)."""
    total = {"total": round((time.perf_counter() - began) * 1e3, 3)}
    start: dict[str, Any] = robot_state_body_empty()
    trajectory = robot_trajectory_body(None, None, "")
    extras: dict[str, Any] = {"status": "invalid", "source": None, "message": str(error or "")}
    extras.update(warnings=[], link=None, max_deviation_m=None, path_id=None, timings_ms=total)
    fraction, code = 0.0, error.code if error is not None else MoveItErrorCode.SUCCESS
    if answer is not None and query is not None:
        model, base = answer.model, query.base_joint
        start = robot_state_body(model, list(map(float, answer.states[0])), base)
        timed = extras_body(answer.details)["joint_trajectory"]
        trajectory = robot_trajectory_body(model, timed, base)
        fraction = answer.fraction
        extras.update(
            status=answer.status.value,
            source=answer.source,
            message=answer.message,
            warnings=[*query.warnings, *answer.warnings],
            link=answer.link,
            max_deviation_m=answer.max_deviation_m,
            path_id=answer.path_id,
            timings_ms={**answer.timings_ms, **total},
        )
    text = str(error) if error is not None else ""
    return {
        "start_state": start,
        "solution": trajectory,
        "fraction": fraction,
        "error_code": {"val": int(code), "message": text, "source": "trajcache"},
        "trajcache": extras,
    }


def robot_state_body_empty() -> dict[str, Any]:
    """An empty `moveit_msgs/RobotState`."""
    return {
        "joint_state": {"name": [], "position": []},
        "multi_dof_joint_state": {"joint_names": [], "transforms": []},
    }
