"""A full MoveIt RobotState read against a model: which joint names mean what, and bounds.

MoveIt clients send every joint of the robot in `joint_state` (other groups' joints, gripper
fingers). Each name is one of:

- a planning joint (or a planar base variable): its value is used;
- a fixed joint of the model (a finger its URDF fixes): ignored, with a warning;
- a movable joint outside the planning joints, held by the robot: its value must be within
  HELD_JOINT_TOLERANCE (rad or m) of the held value; a mimic joint of a planning joint must be
  within it of its leader's value times the multiplier plus the offset;
- anything else: unknown.

Every unknown name, and every joint that disagrees, is named in one message, not one per try.

Bounds are applied as MoveIt applies them. A start at most START_STATE_MAX_BOUNDS_ERROR outside
a joint's limits is moved onto the limit, with a warning, as MoveIt's FixStartStateBounds
adapter does with its `start_state_max_bounds_error` (0.05 by default); a goal position outside
the limits is moved onto the limit when its joint constraint's tolerances reach it (MoveIt
samples a goal within the tolerances and the limits). Farther out is refused, printing the
value, the limit and the gap with enough digits to see why.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from trajcache.geometry.model.robot import KinematicJoint, RobotModel
from trajcache.geometry.model.shapes import FloatArray

HELD_JOINT_TOLERANCE = 1e-3  # rad or m: a held joint's value in a request may be this far off
START_STATE_MAX_BOUNDS_ERROR = 0.05  # as MoveIt's FixStartStateBounds default


@dataclass(frozen=True)
class JointReading:
    """Joint names of a state or goal sorted by what they mean to the model."""

    values: dict[str, float] = field(default_factory=dict)  # planning joints (state names)
    fixed: list[str] = field(default_factory=list)
    others: dict[str, float] = field(default_factory=dict)  # held or mimic joints, as given
    unknown: list[str] = field(default_factory=list)


def held_targets(model: RobotModel, held: Mapping[str, float]) -> dict[str, float]:
    """Where the robot holds each movable joint outside its planning joints: the model's values,
    the robot's own `held` over them, and mimic joints following a leader the robot moved."""
    targets = {**model.held_values, **held}
    for joint in model.joints:
        if joint.mimic is not None and joint.index < 0 and joint.mimic[0] in held:
            leader, multiplier, offset = joint.mimic
            targets[joint.name] = multiplier * targets[leader] + offset
    return targets


def fixed_joints(model: RobotModel) -> frozenset[str]:
    """Names of the model's fixed joints."""
    return frozenset(j.name for j in model.joints if j.kind == "fixed")


def planning_mimics(model: RobotModel) -> dict[str, KinematicJoint]:
    """Joints that mimic a planning joint, by name (they move with their leader)."""
    return {j.name: j for j in model.joints if j.mimic is not None and j.index >= 0}


def disagreements(
    model: RobotModel, reading: JointReading, state: FloatArray, targets: Mapping[str, float]
) -> list[str]:
    """`name = given, held at value` for every held or mimic joint off by more than the
    tolerance, given the planning joints' `state`."""
    mimics = planning_mimics(model)
    out: list[str] = []
    for name, given in reading.others.items():
        if name in mimics:
            joint = mimics[name]
            expected = joint.scale * float(state[joint.index]) + joint.offset
            how = "follows its leader at"
        else:
            expected, how = targets[name], "held at"
        if not abs(given - expected) <= HELD_JOINT_TOLERANCE:
            out.append(f"{name} = {given:.10g}, {how} {expected:.10g}")
    return out


def _fmt(value: float) -> str:
    return f"{value:.10g}"


def out_of_bounds(name: str, value: float, lower: float, upper: float) -> str:
    """`name = v < lower (lower limit), by gap`: the digits say why."""
    if value < lower:
        return f"{name} = {_fmt(value)} < {_fmt(lower)} (lower limit), by {lower - value:.3g}"
    return f"{name} = {_fmt(value)} > {_fmt(upper)} (upper limit), by {value - upper:.3g}"


def bounded_dims(model: RobotModel) -> range:
    """State indices with joint limits: the planning joints (not a planar base's x, y, θ)."""
    return range(model.arm_offset, model.dof)


def clamp_start(model: RobotModel, state: FloatArray, warnings: list[str]) -> list[str]:
    """Move start values within START_STATE_MAX_BOUNDS_ERROR of a limit onto it (in place, with
    a warning); answer what lies farther out."""
    refused: list[str] = []
    names = model.state_names
    for d in bounded_dims(model):
        value, lower, upper = float(state[d]), float(model.lower[d]), float(model.upper[d])
        if lower <= value <= upper:
            continue
        text = out_of_bounds(names[d], value, lower, upper)
        if lower - START_STATE_MAX_BOUNDS_ERROR <= value <= upper + START_STATE_MAX_BOUNDS_ERROR:
            state[d] = np.clip(value, lower, upper)
            warnings.append(
                f"start_state: {text}, within start_state_max_bounds_error="
                f"{START_STATE_MAX_BOUNDS_ERROR:g}: moved onto the limit, as MoveIt does"
            )
        else:
            refused.append(f"{text}, beyond start_state_max_bounds_error="
                           f"{START_STATE_MAX_BOUNDS_ERROR:g}")  # fmt: skip
    return refused


def clamp_goal(
    model: RobotModel, name: str, value: float, tolerances: tuple[float, float]
) -> tuple[float, str | None, str | None]:
    """A goal position for state name `name` moved onto its limit when its tolerances (below,
    above) reach it: (value, warning, refusal)."""
    d = model.state_names.index(name)
    if d < model.arm_offset:
        return value, None, None
    lower, upper = float(model.lower[d]), float(model.upper[d])
    if lower <= value <= upper:
        return value, None, None
    below, above = tolerances
    text = out_of_bounds(name, value, lower, upper)
    if value - below <= upper and value + above >= lower:
        clamped = min(max(value, lower), upper)
        return clamped, f"{text}, within its tolerances: moved onto the limit", None
    return value, None, f"{text}, beyond its tolerances (below {below:g}, above {above:g})"
