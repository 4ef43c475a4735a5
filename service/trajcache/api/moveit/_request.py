"""A MotionPlanRequest as the native plan request, read against the robot's model.

Start: `start_state.joint_state`, by name: every planning joint, and joints held outside the
planning joints only at their held values. A planar base's pose is the first joint of
`start_state.multi_dof_joint_state` (translation x and y; a rotation about z, its yaw), unless
the joint state names `base_x`, `base_y` and `base_theta` itself.

Goal: the first of `goal_constraints` whose joint constraints cover every planning joint and
that holds no other kind of constraint; the goal is their positions, which lie within any
tolerances ≥ 0. A planar base's goal is given by joint constraints named `base_x`, `base_y`,
`base_theta`, or `<joint>/x`, `<joint>/y`, `<joint>/theta` (a MoveIt planar joint's variables);
a base variable the goal leaves free stays where it starts, which satisfies the goal. A
constraint on a held joint must allow its held value.

What cannot be used is a MotionPlanError with MoveIt's code: INVALID_ROBOT_STATE for the start,
INVALID_GOAL_CONSTRAINTS for the goal.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass

from trajcache.api.answer_extras import TimingOptions
from trajcache.api.moveit._codes import MotionPlanError, MoveItErrorCode
from trajcache.api.moveit._messages import (
    Constraints,
    JointConstraint,
    MotionPlanRequestIn,
    Quaternion,
    RobotState,
)
from trajcache.core.config import Settings
from trajcache.geometry.errors import SceneError, StateError
from trajcache.geometry.model.kinematics import (
    HELD_TOLERANCE,
    check_limits,
    check_states,
    resolve_state,
)
from trajcache.geometry.model.robot import BASE_STATE_NAMES, BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.fields import unit_quaternion
from trajcache.services.plan.flow import PlanOptions, PlanRequest
from trajcache.services.plan.options import resolve_request

BASE_VARIABLES = {"x": "base_x", "y": "base_y", "theta": "base_theta"}
DEFAULT_BASE_JOINT = "base"  # the planar base's name in an answer when the request gives none
TILT_TOLERANCE = 1e-3  # largest |(qx, qy)| of a planar base's unit quaternion (≈ 0.1°)
SAMPLE_PERIOD_S = 0.1  # answer points every 0.1 s, as MoveIt's time parameterization samples

_START = MoveItErrorCode.INVALID_ROBOT_STATE
_GOAL = MoveItErrorCode.INVALID_GOAL_CONSTRAINTS


@dataclass(frozen=True)
class MotionPlanQuery:
    """What a MotionPlanRequest asks, in native terms."""

    request: PlanRequest
    start: FloatArray  # the start state, in the model's state_names order
    timing: TimingOptions  # toppra with MoveIt's velocity and acceleration scaling factors
    base_joint: str  # name of the planar base's multi-DOF joint in the answer


def motion_plan_query(
    message: MotionPlanRequestIn, *, model: RobotModel, settings: Settings
) -> MotionPlanQuery:
    """The native plan request of `message`; a budget above the service's limit is a 422."""
    planar = model.base is BaseType.PLANAR
    start_values = _start_values(message.start_state, model.state_names, planar)
    start = _checked(model, start_values, "start", _START)
    goal_values = _goal_values(message.goal_constraints, model, start)
    _checked(model, goal_values, "goal", _GOAL)
    request = resolve_request(
        settings=settings,
        start=start_values,
        goal=goal_values,
        # 0 s: the default budget; above the limit a 422, as natively
        options=PlanOptions(
            budget_s=message.allowed_planning_time or None, planner=message.planner_id or None
        ),
        names={"budget_s": "allowed_planning_time"},
    )
    timing = TimingOptions(
        velocity_scaling=message.max_velocity_scaling_factor or 1.0,
        acceleration_scaling=message.max_acceleration_scaling_factor or 1.0,
        sample_period_s=SAMPLE_PERIOD_S,
    )
    base_joint = _base_joint(message) if planar else DEFAULT_BASE_JOINT
    return MotionPlanQuery(request, start, timing, base_joint)


def _checked(
    model: RobotModel, values: dict[str, float], name: str, code: MoveItErrorCode
) -> FloatArray:
    """The state `values` give, in state_names order, or a MotionPlanError naming the problem."""
    try:
        state = check_states(model, resolve_state(model, values, name=name), name=name)[0]
        check_limits(model, state, name=name)
    except StateError as exc:
        raise MotionPlanError(code, str(exc)) from None
    return state


def _variable(name: str, state_names: Collection[str], planar: bool) -> str:
    """The state name a joint name stands for: a planar joint's `<joint>/x` is `base_x`."""
    if planar and name not in state_names:
        head, slash, tail = name.rpartition("/")
        if slash and head and tail in BASE_VARIABLES:
            return BASE_VARIABLES[tail]
    return name


def _start_values(state: RobotState, state_names: Sequence[str], planar: bool) -> dict[str, float]:
    values: dict[str, float] = {}
    joints = state.joint_state
    for name, position in zip(joints.name, joints.position, strict=True):
        key = _variable(name, state_names, planar)
        if key in values:
            raise MotionPlanError(_START, f"start_state.joint_state names {key!r} twice")
        values[key] = position
    multi_dof = state.multi_dof_joint_state
    if planar and multi_dof.joint_names:
        where = f"start_state.multi_dof_joint_state {multi_dof.joint_names[0]!r}"
        translation, rotation = multi_dof.planar(0)
        pose = zip(
            BASE_STATE_NAMES, (translation.x, translation.y, _yaw(rotation, where)), strict=True
        )
        for key, value in pose:
            given = values.setdefault(key, value)  # the joint state may give it too: same value
            gap = given - value
            if key == "base_theta":
                gap = math.remainder(gap, 2 * math.pi)
            if abs(gap) > HELD_TOLERANCE:
                raise MotionPlanError(
                    _START,
                    f"start_state: {key} = {given:.6g} in joint_state, {value:.6g} in {where}",
                )
    return values


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


def _goal_values(
    goals: Sequence[Constraints], model: RobotModel, start: FloatArray
) -> dict[str, float]:
    """The positions of the first goal that covers every planning joint (see the module)."""
    planar = model.base is BaseType.PLANAR
    mixed: list[int] = []
    for index, goal in enumerate(goals):
        named = {_variable(c.joint_name, model.state_names, planar) for c in goal.joint_constraints}
        if not goal.joint_constraints or not named.issuperset(model.joint_names):
            continue
        if goal.other_kinds():
            mixed.append(index)
            continue
        values = _joint_goal(goal.joint_constraints, f"goal_constraints[{index}]", model)
        if planar:
            for key, value in zip(BASE_STATE_NAMES, start[:3], strict=True):
                values.setdefault(key, float(value))
        return values
    raise MotionPlanError(_GOAL, _why_no_goal(goals, model, mixed))


def _joint_goal(
    constraints: Sequence[JointConstraint], where: str, model: RobotModel
) -> dict[str, float]:
    planar = model.base is BaseType.PLANAR
    values: dict[str, float] = {}
    for c in constraints:
        if c.tolerance_above < 0 or c.tolerance_below < 0:
            raise MotionPlanError(_GOAL, f"{where}: {c.joint_name!r} has a negative tolerance")
        key = _variable(c.joint_name, model.state_names, planar)
        if key in model.state_names:
            if values.setdefault(key, c.position) != c.position:
                raise MotionPlanError(_GOAL, f"{where} puts {key!r} at two positions")
            continue
        held = model.held_values.get(c.joint_name)
        if held is None:
            raise MotionPlanError(
                _GOAL,
                f"{where}: {c.joint_name!r} is neither a planning joint "
                f"({', '.join(model.state_names)}) nor a held joint",
            )
        low = c.position - c.tolerance_below - HELD_TOLERANCE
        high = c.position + c.tolerance_above + HELD_TOLERANCE
        if not low <= held <= high:
            raise MotionPlanError(
                _GOAL,
                f"{where}: {c.joint_name} must be within [{low:.6g}, {high:.6g}], but the model "
                f"holds it at {held:.6g} (held joints are set at registration)",
            )
    return values


def _why_no_goal(goals: Sequence[Constraints], model: RobotModel, mixed: list[int]) -> str:
    joints = ", ".join(model.joint_names)
    if mixed:
        kinds = " and ".join(goals[mixed[0]].other_kinds())
        return (
            f"goal_constraints[{mixed[0]}] adds {kinds} to its joint constraints: not supported, "
            f"give joint constraints only ({joints})"
        )
    if any(goal.other_kinds() for goal in goals):
        return (
            "goals given as position or orientation constraints are not supported: give joint "
            f"constraints on every planning joint ({joints})"
        )
    if not goals:
        return (
            f"goal_constraints is empty: give joint constraints on every planning joint ({joints})"
        )
    planar = model.base is BaseType.PLANAR
    named = {_variable(c.joint_name, model.state_names, planar) for c in goals[0].joint_constraints}
    missing = [n for n in model.joint_names if n not in named]
    return (
        f"no goal constrains every planning joint: goal_constraints[0] lacks {', '.join(missing)}"
    )


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
