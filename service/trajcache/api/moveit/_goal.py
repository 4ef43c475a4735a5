"""The goal of a MotionPlanRequest: the first of its `goal_constraints` usable as a joint goal,
else the first given as a link's pose (`pose_goal`).

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

import math
from collections.abc import Collection, Mapping, Sequence
from typing import Any

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
from trajcache.services.plan.attempt import GoalPose

BASE_VARIABLES = {"x": "base_x", "y": "base_y", "theta": "base_theta"}

_GOAL = MoveItErrorCode.INVALID_GOAL_CONSTRAINTS


def state_variable(name: str, state_names: Collection[str], base: BaseType) -> str:
    """The state name a joint name stands for: a planar joint's `<joint>/x` is `base_x`."""
    if base is BaseType.PLANAR and name not in state_names:
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
    mixed: list[int] = []
    for index, goal in enumerate(goals):
        named = {
            state_variable(c.joint_name, model.state_names, model.base)
            for c in goal.joint_constraints
        }
        if not goal.joint_constraints or not named.issuperset(model.joint_names):
            continue
        if goal.other_kinds():
            mixed.append(index)
            continue
        where = f"goal_constraints[{index}]"
        values = _joint_goal(goal.joint_constraints, where, model, held, warnings)
        if model.base is BaseType.PLANAR:
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
    fixed, mimics = fixed_joints(model), planning_mimics(model)
    values: dict[str, float] = {}
    ignored: list[str] = []
    others: list[JointConstraint] = []
    unknown: list[str] = []
    refused: list[str] = []
    for c in constraints:
        if c.tolerance_above < 0 or c.tolerance_below < 0:
            raise MotionPlanError(_GOAL, f"{where}: {c.joint_name!r} has a negative tolerance")
        key = state_variable(c.joint_name, model.state_names, model.base)
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
            "no goal is joint constraints on every planning joint, nor one position constraint "
            f"with at most one orientation constraint on its link (planning joints: {joints})"
        )
    if not goals:
        return (
            f"goal_constraints is empty: give joint constraints on every planning joint ({joints})"
        )
    named = {
        state_variable(c.joint_name, model.state_names, model.base)
        for c in goals[0].joint_constraints
    }
    missing = [n for n in model.joint_names if n not in named]
    return (
        f"no goal constrains every planning joint: goal_constraints[0] lacks {', '.join(missing)}"
    )


def pose_goal(goals: Sequence[Constraints], model: RobotModel) -> GoalPose | None:
    """The first goal given as a position constraint (with at most one orientation constraint
    on the same link, and nothing else) as a pose goal; None when no entry is one.

    Read as MoveIt defines them, conservatively: the constraint region's first primitive, a
    SPHERE (its radius) or a BOX (half its smallest side: the sphere inside it), at its first
    primitive pose's position, is the position tolerance; the smallest of the absolute axis
    tolerances is the largest rotation angle allowed (an angle within it is within each axis'
    tolerance). Without an orientation constraint any orientation does. Refused (a
    MotionPlanError): a frame other than the model's root (or `world`), a target point offset,
    and a region of another shape.
    """
    for index, goal in enumerate(goals):
        if goal.joint_constraints or goal.visibility_constraints:
            continue
        if len(goal.position_constraints) != 1 or len(goal.orientation_constraints) > 1:
            continue
        where = f"goal_constraints[{index}]"
        position = goal.position_constraints[0]
        link = str(position.get("link_name", ""))
        center, tolerance = _region(position, model, f"{where}.position_constraints[0]")
        quaternion, angle = (0.0, 0.0, 0.0, 1.0), math.pi
        if goal.orientation_constraints:
            quaternion, angle = _orientation(
                goal.orientation_constraints[0], link, model, f"{where}.orientation_constraints[0]"
            )
        return GoalPose(link, center, quaternion, tolerance, angle)
    return None


def _frame(message: Mapping[str, Any], model: RobotModel, where: str) -> None:
    frame = str((message.get("header") or {}).get("frame_id", "")).lstrip("/")
    if frame not in ("", "world", model.link_names[0]):
        raise MotionPlanError(
            _GOAL, f"{where}.header.frame_id: {frame!r} is not the model's root frame "
            f"({model.link_names[0]!r})",
        )  # fmt: skip


def _components(value: Any, names: str, where: str) -> tuple[float, ...]:
    if isinstance(value, Mapping):
        value = [value.get(n, 1.0 if n == "w" else 0.0) for n in names]
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        out = ()
    if len(out) != len(names) or not all(math.isfinite(v) for v in out):
        raise MotionPlanError(_GOAL, f"{where}: {len(names)} finite values expected")
    return out


def _region(
    message: Mapping[str, Any], model: RobotModel, where: str
) -> tuple[tuple[float, float, float], float]:
    """The position constraint's center and the radius of a sphere inside its region."""
    _frame(message, model, where)
    offset = _components(message.get("target_point_offset") or [0, 0, 0], "xyz", where)
    if any(offset):
        raise MotionPlanError(_GOAL, f"{where}.target_point_offset: only a zero offset is read")
    region = message.get("constraint_region") or {}
    shapes, poses = region.get("primitives") or [], region.get("primitive_poses") or []
    if len(shapes) != 1 or len(poses) != 1:
        raise MotionPlanError(_GOAL, f"{where}.constraint_region: one primitive and its pose")
    kind = str(shapes[0].get("type", "")).lower()
    dims = [float(d) for d in shapes[0].get("dimensions") or []]
    if kind in ("2", "sphere") and len(dims) >= 1 and dims[0] > 0:
        radius = dims[0]
    elif kind in ("1", "box") and len(dims) == 3 and min(dims) > 0:
        radius = min(dims) / 2.0
    else:
        raise MotionPlanError(
            _GOAL, f"{where}.constraint_region: a SPHERE (2) or a BOX (1) with positive size"
        )
    x, y, z = _components(poses[0].get("position", [0, 0, 0]), "xyz", f"{where} position")
    return (x, y, z), radius


def _orientation(
    message: Mapping[str, Any], link: str, model: RobotModel, where: str
) -> tuple[tuple[float, float, float, float], float]:
    """The orientation constraint's quaternion and its smallest axis tolerance."""
    _frame(message, model, where)
    if str(message.get("link_name", "")) != link:
        raise MotionPlanError(_GOAL, f"{where}.link_name must be the position constraint's")
    qx, qy, qz, qw = _components(message.get("orientation", [0, 0, 0, 1]), "xyzw", where)
    axes = [float(message.get(f"absolute_{a}_axis_tolerance", 0.0)) for a in "xyz"]
    if min(axes) <= 0.0:
        raise MotionPlanError(_GOAL, f"{where}: the absolute axis tolerances must be positive")
    return (qx, qy, qz, qw), min(min(axes), math.pi)
