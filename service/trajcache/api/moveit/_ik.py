"""MoveIt's `GetPositionIK` over HTTP: `{"ik_request": PositionIKRequest}` in, `{solution,
error_code}` out, answered by the native IK (`services.ik.solve`).

Read: `ik_link_name` (empty: the model's end-effector link; an SRDF end effector: its parent
link), `pose_stamped` (`header.frame_id` '', `world`, `map` or `odom`: the world frame; the
model's root link: the base frame, placed by the seed's base pose for a planar base),
`robot_state` (the seed, read as a plan's `start_state`; empty: the robot's zero state),
`avoid_collisions` (MoveIt's default, false), `timeout` (the budget; 0: the service's default,
above its maximum: clamped, with a warning). Ignored, with a warning: `group_name` (the
model's planning joints move) and ROS 1's `attempts`. Refused (422): `constraints`, and more
than one pose (`pose_stamped_vector`, several `ik_link_names`): trajcache cannot honour them.
Tolerances are the native defaults (1 mm, 0.01 rad). A planar base never moves here.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field, field_validator, model_validator
from scipy.spatial.transform import Rotation

from trajcache.api.moveit._codes import MotionPlanError, MoveItErrorCode
from trajcache.api.moveit._messages import (
    Constraints,
    Name,
    Names,
    Pose,
    RobotState,
    _Message,
    _not_supported,
)
from trajcache.api.moveit._request import read_start_state
from trajcache.api.moveit._response import robot_state_body
from trajcache.api.moveit._schemas import ErrorCodeOut, RobotStateOut
from trajcache.api.moveit._state import held_targets
from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import pose_matrix
from trajcache.geometry.scene.fields import unit_quaternion
from trajcache.services.ik.solve import IK_BUDGET_MAX_S, IkAnswer, IkRequest, IkStatus

WORLD_FRAMES = ("", "world", "map", "odom")
DEFAULT_BASE_JOINT = "base"


class Duration(_Message):
    """`builtin_interfaces/Duration` (ROS 2 `sec`, `nanosec`) or ROS 1's (`secs`, `nsecs`)."""

    sec: int = 0
    nanosec: int = 0
    secs: int = 0
    nsecs: int = 0

    def seconds(self) -> float:
        """The duration in seconds."""
        return self.sec + self.secs + (self.nanosec + self.nsecs) * 1e-9


class PoseStamped(_Message):
    """`geometry_msgs/PoseStamped`."""

    header: dict[str, Any] = Field(default_factory=dict)
    pose: Pose = Field(default_factory=Pose)

    def frame(self) -> str:
        """`header.frame_id`, without a leading slash."""
        return str(self.header.get("frame_id") or "").lstrip("/")


class PositionIKRequest(_Message):
    """`moveit_msgs/PositionIKRequest`."""

    group_name: Name = Field(default="", description="Ignored: the planning joints move.")
    robot_state: RobotState = Field(default_factory=RobotState)
    constraints: Constraints = Field(
        default_factory=Constraints, description="Not supported: must be empty."
    )
    avoid_collisions: bool = False
    ik_link_name: Name = ""
    pose_stamped: PoseStamped = Field(default_factory=PoseStamped)
    ik_link_names: Names = Field(default_factory=list)
    pose_stamped_vector: Annotated[list[PoseStamped], Field(max_length=64)] = Field(
        default_factory=list
    )
    timeout: Duration = Field(default_factory=Duration)
    attempts: int = Field(default=0, ge=0, description="Ignored (ROS 1).")

    @field_validator("constraints")
    @classmethod
    def _no_constraints(cls, value: Constraints) -> Constraints:
        if not value.is_empty():
            raise ValueError(_not_supported("IK constraints"))
        return value

    @model_validator(mode="after")
    def _one_pose(self) -> PositionIKRequest:
        links = set(self.ik_link_names) - {self.ik_link_name}
        if len(links) > 1 or (links and self.ik_link_name) or len(self.pose_stamped_vector) > 1:
            raise ValueError(_not_supported("IK for several links or poses at once"))
        if links:
            self.ik_link_name = links.pop()
        if self.pose_stamped_vector:
            self.pose_stamped = self.pose_stamped_vector[0]
        return self


class GetPositionIKIn(_Message):
    """`moveit_msgs/GetPositionIK` request: `{"ik_request": {...}}`."""

    ik_request: PositionIKRequest


class TrajcacheIkOut(BaseModel):
    """How the native IK answered, for operators (not part of MoveIt's message)."""

    status: Literal["success", "not_found", "in_collision", "invalid"] = Field(
        description="The native IK status; 'invalid': refused before solving, the error code "
        "says why."
    )
    message: str
    warnings: list[str] = Field(description="What of the request was ignored or clamped.")
    link: str | None = Field(description="The link posed.")
    position_error: float | None = Field(description="Of the solution (m).")
    orientation_error: float | None = Field(description="Of the solution (rad).")
    timings_ms: dict[str, float]


class GetPositionIKOut(BaseModel):
    """A `moveit_msgs/GetPositionIK` response, plus `trajcache`: how it was answered."""

    solution: RobotStateOut = Field(description="Empty unless error_code.val is 1.")
    error_code: ErrorCodeOut
    trajcache: TrajcacheIkOut


@dataclass(frozen=True)
class IkQuery:
    """A GetPositionIK request in native terms."""

    request: IkRequest
    base_joint: str
    warnings: tuple[str, ...]


def ik_query(message: GetPositionIKIn, *, model: RobotModel, held: Mapping[str, float]) -> IkQuery:
    """The native IK request of `message`; MotionPlanError with MoveIt's code when unusable."""
    ik = message.ik_request
    warnings: list[str] = []
    seed = None
    state = ik.robot_state
    if state.joint_state.name or state.multi_dof_joint_state.joint_names:
        try:
            seed = read_start_state(state, model, held_targets(model, held), warnings)
        except MotionPlanError as exc:
            text = str(exc).replace("start_state", "ik_request.robot_state")
            raise MotionPlanError(exc.code, text) from None
        warnings = [w.replace("start_state", "ik_request.robot_state") for w in warnings]
    position, orientation = pose_in_base_frame(
        ik.pose_stamped,
        model,
        seed,
        ("ik_request.pose_stamped.header.frame_id", "ik_request.pose_stamped.pose.orientation"),
    )
    budget = ik.timeout.seconds()
    if budget > IK_BUDGET_MAX_S:
        warnings.append(f"timeout {budget:g} s is above the most, {IK_BUDGET_MAX_S:g} s: clamped")
    if ik.group_name:
        warnings.append(f"group_name {ik.group_name!r} is ignored: the planning joints move")
    if ik.attempts:
        warnings.append("attempts is ignored (ROS 1): restarts run until the timeout")
    request = IkRequest(
        link=ik.ik_link_name,
        position=position,
        orientation=orientation,
        seed=None if seed is None else list(map(float, seed)),
        avoid_collisions=ik.avoid_collisions,
        budget_s=min(budget, IK_BUDGET_MAX_S) if budget > 0 else None,
        names={
            "link": "ik_request.ik_link_name",
            "seed": "ik_request.robot_state",
            "orientation": "ik_request.pose_stamped.pose.orientation",
        },
    )
    multi_dof = state.multi_dof_joint_state.joint_names
    return IkQuery(request, multi_dof[0] if multi_dof else DEFAULT_BASE_JOINT, tuple(warnings))


def pose_in_base_frame(
    stamped: PoseStamped, model: RobotModel, seed: Any, names: tuple[str, str]
) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """The pose in the frame IK reads (the world's; for a fixed base, its root link's);
    `names`: the frame's and the orientation's fields, as errors name them."""
    frame, pose = stamped.frame(), stamped.pose
    position = (pose.position.x, pose.position.y, pose.position.z)
    o = pose.orientation
    orientation = (o.x, o.y, o.z, o.w)
    root = model.link_names[0]
    if frame in WORLD_FRAMES or (frame == root and model.base is BaseType.FIXED):
        return position, orientation
    if frame != root:
        raise MotionPlanError(
            MoveItErrorCode.FRAME_TRANSFORM_FAILURE,
            f"{names[0]} {frame!r} is neither the world "
            f"({', '.join(repr(f) for f in WORLD_FRAMES[1:])}) nor the root link {root!r}",
        )
    x, y, theta = (0.0, 0.0, 0.0) if seed is None else (float(v) for v in seed[:3])
    quaternion = unit_quaternion(list(orientation), names[1])
    base = pose_matrix([x, y, 0.0], [0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2)])
    world = base @ pose_matrix(list(position), quaternion)
    return _pose_parts(world)


def _pose_parts(
    pose: Any,
) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """Position and (x, y, z, w) quaternion of a 4×4 pose."""
    x, y, z, w = Rotation.from_matrix(pose[:3, :3]).as_quat()
    p = pose[:3, 3]
    return (float(p[0]), float(p[1]), float(p[2])), (float(x), float(y), float(z), float(w))


def ik_response(
    *,
    answer: IkAnswer | None,
    query: IkQuery | None,
    code: MoveItErrorCode,
    text: str,
    began: float,
) -> dict[str, Any]:
    """The GetPositionIK response, and trajcache's account of it."""
    solution: dict[str, Any] = {
        "joint_state": {"name": [], "position": []},
        "multi_dof_joint_state": {"joint_names": [], "transforms": []},
    }
    if answer is not None and answer.state is not None and query is not None:
        state = list(map(float, answer.state))
        solution = robot_state_body(answer.model, state, query.base_joint)
    total = {"total": round((time.perf_counter() - began) * 1e3, 3)}
    extras: dict[str, Any] = {
        "status": answer.status.value if answer is not None else "invalid",
        "message": text,
        "warnings": list(query.warnings) if query is not None else [],
        "link": answer.link if answer is not None else None,
        "position_error": answer.result.position_error if answer is not None else None,
        "orientation_error": answer.result.orientation_error if answer is not None else None,
        "timings_ms": {**answer.timings_ms, **total} if answer is not None else total,
    }
    return {
        "solution": solution,
        "error_code": {"val": int(code), "message": text, "source": "trajcache"},
        "trajcache": extras,
    }


def answer_code(answer: IkAnswer) -> MoveItErrorCode:
    """SUCCESS, or NO_IK_SOLUTION (whether none was found or all were in collision)."""
    if answer.status is IkStatus.SUCCESS:
        return MoveItErrorCode.SUCCESS
    return MoveItErrorCode.NO_IK_SOLUTION
