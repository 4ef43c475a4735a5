"""A MotionPlanRequest as the native plan request, read against the robot's model.

Start: `start_state.joint_state`, by name, read as a full MoveIt RobotState (`_state`): every
planning joint; fixed joints ignored; held and mimic joints where the robot holds them. A planar
base's pose is the first joint of `start_state.multi_dof_joint_state` (translation x and y; a
rotation about z, its yaw), unless the joint state names `base_x`, `base_y` and `base_theta`
itself; for a fixed base that field is ignored. Goal: `_goal`.

Read differently from MoveIt, with a warning in the answer: an unknown `planner_id` (the
service's default planner plans), an `allowed_planning_time` above the service's maximum (it is
clamped), bounds fixed as MoveIt's adapters fix them (`_state`), and fields that are ignored.

What cannot be used is a MotionPlanError with MoveIt's code: INVALID_ROBOT_STATE for the start,
INVALID_GOAL_CONSTRAINTS for the goal.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from trajcache.api.answer_extras import TimingOptions
from trajcache.api.moveit._codes import MotionPlanError, MoveItErrorCode
from trajcache.api.moveit._goal import BASE_VARIABLES, goal_values, pose_goal, state_variable
from trajcache.api.moveit._ignored import ignored_fields, planner_and_budget
from trajcache.api.moveit._messages import MotionPlanRequestIn, Quaternion, RobotState
from trajcache.api.moveit._state import (
    HELD_JOINT_TOLERANCE,
    JointReading,
    clamp_start,
    disagreements,
    fixed_joints,
    held_targets,
    planning_mimics,
)
from trajcache.core.config import Settings
from trajcache.geometry.errors import SceneError, StateError
from trajcache.geometry.model.kinematics import check_limits, check_states, resolve_state
from trajcache.geometry.model.robot import BASE_STATE_NAMES, BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.fields import unit_quaternion
from trajcache.services.plan.flow import PlanOptions, PlanRequest
from trajcache.services.plan.options import resolve_request

DEFAULT_BASE_JOINT = "base"  # the planar base's name in an answer when the request gives none
TILT_TOLERANCE = 1e-3  # largest |(qx, qy)| of a planar base's unit quaternion (≈ 0.1°)
SAMPLE_PERIOD_S = 0.1  # answer points every 0.1 s, as MoveIt's time parameterization samples

_START = MoveItErrorCode.INVALID_ROBOT_STATE
_GOAL = MoveItErrorCode.INVALID_GOAL_CONSTRAINTS


@dataclass(frozen=True)
class MotionPlanQuery:
    """What a MotionPlanRequest asks, in native terms, and what was read differently."""

    request: PlanRequest
    start: FloatArray  # the start state, in the model's state_names order
    timing: TimingOptions  # toppra with MoveIt's velocity and acceleration scaling factors
    base_joint: str  # name of the planar base's multi-DOF joint in the answer
    warnings: tuple[str, ...] = ()  # fields read differently from MoveIt, or ignored


def motion_plan_query(
    message: MotionPlanRequestIn,
    *,
    model: RobotModel,
    settings: Settings,
    held: Mapping[str, float] | None = None,
) -> MotionPlanQuery:
    """The native plan request of `message` for a robot of `model` holding its joints outside
    the planning joints at `held` (default: the model's held values)."""
    targets = held_targets(model, held or {})
    warnings: list[str] = []
    start = read_start_state(message.start_state, model, targets, warnings)
    goal: dict[str, float] | None = None
    pose = None
    if not _joint_goal_given(message, model):
        pose = pose_goal(message.goal_constraints, model)
    if pose is None:
        goal = goal_values(
            message.goal_constraints, model=model, start=start, held=targets, warnings=warnings
        )
        _checked(model, goal, "goal", _GOAL)
    planner, budget_s = planner_and_budget(message, settings, warnings)
    request = resolve_request(
        settings=settings,
        start=dict(zip(model.state_names, map(float, start), strict=True)),
        goal=goal,
        options=PlanOptions(budget_s=budget_s, planner=planner),
        names={"budget_s": "allowed_planning_time"},
        goal_pose=pose,
    )
    timing = TimingOptions(
        velocity_scaling=message.max_velocity_scaling_factor or 1.0,
        acceleration_scaling=message.max_acceleration_scaling_factor or 1.0,
        sample_period_s=SAMPLE_PERIOD_S,
    )
    base_joint = DEFAULT_BASE_JOINT
    if model.base is BaseType.PLANAR:
        base_joint = _base_joint(message)
    warnings += ignored_fields(message, model.base)
    return MotionPlanQuery(request, start, timing, base_joint, tuple(warnings))


def _joint_goal_given(message: MotionPlanRequestIn, model: RobotModel) -> bool:
    """Whether some goal entry holds joint constraints (then the goal is read as joints)."""
    return any(goal.joint_constraints for goal in message.goal_constraints)


def read_start_state(
    state: RobotState, model: RobotModel, targets: Mapping[str, float], warnings: list[str]
) -> FloatArray:
    """The state of a full MoveIt RobotState, bounds fixed as MoveIt fixes a start's; every
    problem named at once (a MotionPlanError with INVALID_ROBOT_STATE)."""
    reading = _read_joint_state(state, model, targets)
    if reading.unknown:
        raise MotionPlanError(
            _START,
            f"start_state.joint_state: {', '.join(map(repr, reading.unknown))} are not joints "
            f"of the robot (planning joints: {', '.join(model.state_names)})",
        )
    if reading.fixed:
        warnings.append(
            f"start_state.joint_state: fixed joints {', '.join(reading.fixed)} are ignored "
            "(they never move)"
        )
    values = dict(reading.values)
    if model.base is BaseType.PLANAR:
        _base_pose(state, values)
    start = _checked(model, values, "start", _START, limits=False).copy()
    wrong = disagreements(model, reading, start, targets)
    if wrong:
        raise MotionPlanError(
            _START,
            f"start_state: joints outside the planning joints are not where the robot holds "
            f"them (tolerance {HELD_JOINT_TOLERANCE:g}): {'; '.join(wrong)}",
        )
    if refused := clamp_start(model, start, warnings):
        raise MotionPlanError(_START, f"start is out of joint limits: {'; '.join(refused)}")
    return _checked(model, start, "start", _START)


def _read_joint_state(
    state: RobotState, model: RobotModel, targets: Mapping[str, float]
) -> JointReading:
    fixed, mimics = fixed_joints(model), planning_mimics(model)
    reading = JointReading()
    joints = state.joint_state
    for name, position in zip(joints.name, joints.position, strict=True):
        key = state_variable(name, model.state_names, model.base)
        if key in reading.values or name in reading.others:
            raise MotionPlanError(_START, f"start_state.joint_state names {key!r} twice")
        if key in model.state_names:
            reading.values[key] = position
        elif name in fixed:
            reading.fixed.append(name)
        elif name in targets or name in mimics:
            reading.others[name] = position
        else:
            reading.unknown.append(name)
    return reading


def _checked(
    model: RobotModel,
    values: Mapping[str, float] | FloatArray,
    name: str,
    code: MoveItErrorCode,
    *,
    limits: bool = True,
) -> FloatArray:
    """The state `values` give, in state_names order, or a MotionPlanError naming the problem."""
    try:
        state = check_states(model, resolve_state(model, values, name=name), name=name)[0]
        if limits:
            check_limits(model, state, name=name)
    except StateError as exc:
        raise MotionPlanError(code, str(exc)) from None
    return state


def _base_pose(state: RobotState, values: dict[str, float]) -> None:
    """A planar base's pose from the first multi-DOF joint, into `values` (which may give it
    by name too: then the same)."""
    multi_dof = state.multi_dof_joint_state
    if not multi_dof.joint_names:
        return
    where = f"start_state.multi_dof_joint_state {multi_dof.joint_names[0]!r}"
    translation, rotation = multi_dof.planar(0)
    pose = zip(BASE_STATE_NAMES, (translation.x, translation.y, _yaw(rotation, where)), strict=True)
    for key, value in pose:
        given = values.setdefault(key, value)
        gap = given - value
        if key == "base_theta":
            gap = math.remainder(gap, 2 * math.pi)
        if abs(gap) > HELD_JOINT_TOLERANCE:
            raise MotionPlanError(
                _START, f"start_state: {key} = {given:.6g} in joint_state, {value:.6g} in {where}"
            )


def _yaw(rotation: Quaternion, where: str) -> float:
    """The angle of a rotation about z; a rotation tilting the base is a MotionPlanError."""
    try:  # an all-zero quaternion (a default-constructed ROS 1 message) is the identity
        x, y, z, w = unit_quaternion(
            rotation.model_dump(), f"{where}.rotation", zero_is_identity=True
        )
    except SceneError as exc:
        raise MotionPlanError(_START, str(exc)) from None
    if math.hypot(x, y) > TILT_TOLERANCE:
        raise MotionPlanError(
            _START, f"{where}: a planar base turns about z only, but it is tilted"
        )
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _base_joint(message: MotionPlanRequestIn) -> str:
    """The planar base's joint name as the request gives it (multi-DOF start, or a goal)."""
    multi_dof = message.start_state.multi_dof_joint_state
    if multi_dof.joint_names:
        return multi_dof.joint_names[0]
    for goal in message.goal_constraints:
        for c in goal.joint_constraints:
            head, slash, tail = c.joint_name.rpartition("/")
            if slash and head and tail in BASE_VARIABLES:
                return head
    return DEFAULT_BASE_JOINT
