"""The goal of a MotionPlanRequest: the first of its `goal_constraints` usable as a joint goal.

The goal is the first entry whose joint constraints cover every planning joint and that holds
no other kind of constraint; it is their positions. A position outside its joint's limits is
moved onto the limit when the constraint's tolerances reach it (`_state.clamp_goal`). A planar
base's goal is given by joint constraints named `base_x`, `base_y`, `base_theta`, or `<joint>/x`,
`<joint>/y`, `<joint>/theta` (a MoveIt planar joint's variables); a base variable the goal
leaves free stays where it starts, which satisfies the goal. A constraint on a held joint must
allow its held value (within `_state.HELD_JOINT_TOLERANCE`); one on a fixed joint is ignored,
with a warning. Every unknown joint, and every held joint the goal moves, is named at once.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence

from trajcache.api.moveit._codes import MotionPlanError, MoveItErrorCode
from trajcache.api.moveit._messages import Constraints, JointConstraint
from trajcache.api.moveit._state import (
    HELD_JOINT_TOLERANCE,
    clamp_goal,
    fixed_joints,
    planning_mimics,
)
from trajcache.geometry.model.robot import BASE_STATE_NAMES, BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray

BASE_VARIABLES = {"x": "base_x", "y": "base_y", "theta": "base_theta"}

_GOAL = MoveItErrorCode.INVALID_GOAL_CONSTRAINTS


def state_variable(name: str, state_names: Collection[str], planar: bool) -> str:
    """The state name a joint name stands for: a planar joint's `<joint>/x` is `base_x`."""
    if planar and name not in state_names:
        head, slash, tail = name.rpartition("/")
        if slash and head and tail in BASE_VARIABLES:
            return BASE_VARIABLES[tail]
    return name


def goal_values(
    goals: Sequence[Constraints],
    *,
    model: RobotModel,
    start: FloatArray,
    held: Mapping[str, float],
    warnings: list[str],
) -> dict[str, float]:
    """The positions of the first goal that covers every planning joint (see the module)."""
    planar = model.base is BaseType.PLANAR
    mixed: list[int] = []
    for index, goal in enumerate(goals):
        named = {
            state_variable(c.joint_name, model.state_names, planar) for c in goal.joint_constraints
        }
        if not goal.joint_constraints or not named.issuperset(model.joint_names):
            continue
        if goal.other_kinds():
            mixed.append(index)
            continue
        where = f"goal_constraints[{index}]"
        values = _joint_goal(goal.joint_constraints, where, model, held, warnings)
        if planar:
            for key, value in zip(BASE_STATE_NAMES, start[:3], strict=True):
                values.setdefault(key, float(value))
        return values
    raise MotionPlanError(_GOAL, _why_no_goal(goals, model, mixed))


def _joint_goal(
    constraints: Sequence[JointConstraint],
    where: str,
    model: RobotModel,
    held: Mapping[str, float],
    warnings: list[str],
) -> dict[str, float]:
    planar = model.base is BaseType.PLANAR
    fixed, mimics = fixed_joints(model), planning_mimics(model)
    values: dict[str, float] = {}
    ignored: list[str] = []
    others: list[JointConstraint] = []
    unknown: list[str] = []
    refused: list[str] = []
    for c in constraints:
        if c.tolerance_above < 0 or c.tolerance_below < 0:
            raise MotionPlanError(_GOAL, f"{where}: {c.joint_name!r} has a negative tolerance")
        key = state_variable(c.joint_name, model.state_names, planar)
        if key in model.state_names:
            position, warning, refusal = clamp_goal(
                model, key, c.position, (c.tolerance_below, c.tolerance_above)
            )
            if values.setdefault(key, position) != position:
                raise MotionPlanError(_GOAL, f"{where} puts {key!r} at two positions")
            warnings += [f"{where}: {warning}"] if warning else []
            refused += [refusal] if refusal else []
        elif c.joint_name in fixed:
            ignored.append(c.joint_name)
        elif c.joint_name in held or c.joint_name in mimics:
            others.append(c)
        else:
            unknown.append(c.joint_name)
    if unknown:
        raise MotionPlanError(
            _GOAL,
            f"{where}: {', '.join(map(repr, unknown))} are neither planning joints "
            f"({', '.join(model.state_names)}) nor joints the robot holds",
        )
    if refused:
        raise MotionPlanError(_GOAL, f"{where} is out of joint limits: {'; '.join(refused)}")
    if ignored:
        warnings.append(f"{where}: fixed joints {', '.join(ignored)} are ignored (they never move)")
    _check_others(others, where, model, held, values)
    return values


def _check_others(
    others: Sequence[JointConstraint],
    where: str,
    model: RobotModel,
    held: Mapping[str, float],
    values: Mapping[str, float],
) -> None:
    """Refuse, naming them all, the held (or mimic) joints whose constraint excludes the value
    the robot gives them."""
    mimics = planning_mimics(model)
    wrong: list[str] = []
    for c in others:
        if c.joint_name in mimics:
            joint = mimics[c.joint_name]
            leader = values.get(model.state_names[joint.index], 0.0)
            expected = joint.scale * leader + joint.offset
        else:
            expected = held[c.joint_name]
        low = c.position - c.tolerance_below - HELD_JOINT_TOLERANCE
        high = c.position + c.tolerance_above + HELD_JOINT_TOLERANCE
        if not low <= expected <= high:
            wrong.append(
                f"{c.joint_name} must be within [{low:.10g}, {high:.10g}], but the robot holds "
                f"it at {expected:.10g}"
            )
    if wrong:
        raise MotionPlanError(
            _GOAL, f"{where}: {'; '.join(wrong)} (held joints are set at registration)"
        )


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
    named = {
        state_variable(c.joint_name, model.state_names, planar) for c in goals[0].joint_constraints
    }
    missing = [n for n in model.joint_names if n not in named]
    return (
        f"no goal constrains every planning joint: goal_constraints[0] lacks {', '.join(missing)}"
    )
