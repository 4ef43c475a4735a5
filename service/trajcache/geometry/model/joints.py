"""The joints of a URDF: planning limits, the planning joints, held and mimic values, and the
kinematic joints built from them.

Planning limits: continuous joints, and revolute joints whose range is wider than a full turn
(e.g. the ±2π of many arms), are planned in a 2π window, [−π, π] whenever the URDF allows it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from trajcache.geometry.errors import RobotModelError
from trajcache.geometry.model.robot import KinematicJoint
from trajcache.geometry.model.srdf import Srdf, group_joints

DEFAULT_JOINT_VELOCITY = 3.14
MOVABLE = ("revolute", "continuous", "prismatic")
Limits = Mapping[str, tuple[float, float, float] | None]


def joint_limits(joint: Any) -> tuple[float, float, float] | None:
    """Planning (lower, upper, velocity) of a movable joint; None for a prismatic joint without
    limits (it can be held, not planned). A revolute joint without limits turns freely."""
    limit = joint.limit
    velocity = getattr(limit, "velocity", None)
    if velocity is None or not math.isfinite(velocity) or velocity <= 0:
        velocity = DEFAULT_JOINT_VELOCITY
    unbounded = limit is None or (limit.lower is None and limit.upper is None)
    if joint.type == "continuous" or (joint.type == "revolute" and unbounded):
        return -math.pi, math.pi, velocity
    if unbounded:
        return None
    lower = 0.0 if limit.lower is None else float(limit.lower)
    upper = 0.0 if limit.upper is None else float(limit.upper)
    if not (math.isfinite(lower) and math.isfinite(upper)) or lower > upper:
        raise RobotModelError(f"joint {joint.name!r} has invalid limits [{lower}, {upper}]")
    if joint.type == "revolute" and upper - lower > 2 * math.pi + 1e-9:
        lower = min(max(-math.pi, lower), upper - 2 * math.pi)
        upper = lower + 2 * math.pi
    return lower, upper, velocity


def planning_joints(
    ordered: list[Any],
    joint_names: Sequence[str] | None,
    group: str | None,
    srdf: Srdf | None,
    warnings: list[str],
) -> list[str]:
    """The planning joints: listed, an SRDF group's movable joints, or every movable joint that
    does not mimic another (both in the URDF's order, `ordered` being the file's joints)."""
    movable = [j.name for j in ordered if j.type in MOVABLE]
    if group is not None:
        if joint_names is not None:
            raise RobotModelError("give either joint_names or group, not both")
        if srdf is None:
            raise RobotModelError(f"group {group!r} needs an SRDF that defines it")
        parent_of = {j.child: (j.name, j.parent) for j in ordered}
        members, skipped = group_joints(
            srdf, group, parent_of=parent_of, joints=[j.name for j in ordered]
        )
        warnings += skipped
        names = [n for n in movable if n in members]
        if not names:
            raise RobotModelError(f"SRDF group {group!r} has no movable joints")
        return names
    if joint_names is None:
        return [j.name for j in ordered if j.type in MOVABLE and j.mimic is None]
    if isinstance(joint_names, str):
        raise RobotModelError("joint_names must be a list of joint names, not a string")
    names = list(joint_names)
    all_joints = {j.name for j in ordered}
    if unknown := [n for n in names if n not in all_joints]:
        raise RobotModelError(f"unknown joint names {unknown}; movable joints are {movable}")
    if fixed := [n for n in names if n not in movable]:
        raise RobotModelError(f"joints {fixed} are not movable and cannot be planned")
    if len(set(names)) != len(names):
        raise RobotModelError(f"joint names are repeated: {names}")
    return names


def held_values(
    ordered: list[Any],
    planning: list[str],
    limits: Limits,
    joint_values: Mapping[str, float] | str | None,
    srdf: Srdf | None,
) -> dict[str, float]:
    """Values of the movable joints outside the planning group.

    Each is 0 clipped into its limits unless `joint_values` gives it (by name, or an SRDF
    group_state's name); a mimic joint follows its leader (multiplier · leader + offset). One
    that follows a planning joint moves with it in every state (`_check_planned_mimic`).
    """
    by_name = {j.name: j for j in ordered}
    followers = _followers(by_name, planning)
    values: dict[str, float] = {}
    for joint in ordered:
        if joint.type in MOVABLE and joint.name not in planning and joint.name not in followers:
            bounds = limits[joint.name]
            values[joint.name] = 0.0 if bounds is None else min(max(0.0, bounds[0]), bounds[1])
    for name, value in _given_values(joint_values, planning, srdf).items():
        _check_given(name, by_name, planning, followers, held=values)
        values[name] = _within_limits(name, value, limits[name])
    _follow_leaders(values, {n: m for n, m in followers.items() if m.joint not in planning})
    return values


def _followers(by_name: Mapping[str, Any], planning: list[str]) -> dict[str, Any]:
    """The mimic of each movable joint that mimics another, after checking it can be followed."""
    followers = {
        j.name: j.mimic for j in by_name.values() if j.type in MOVABLE and j.mimic is not None
    }
    for name, mimic in followers.items():
        leader = by_name.get(mimic.joint)
        if leader is None or leader.type not in MOVABLE:
            raise RobotModelError(f"joint {name!r} mimics {mimic.joint!r}, not a movable joint")
        if name in planning:
            raise RobotModelError(
                f"joint {name!r} mimics {mimic.joint!r}: plan with {mimic.joint!r}, not with it"
            )
        if mimic.joint in planning:
            _check_planned_mimic(by_name, name, mimic)
    return followers


def _given_values(
    joint_values: Mapping[str, float] | str | None, planning: list[str], srdf: Srdf | None
) -> Mapping[str, float]:
    """The held values asked for: by name, or an SRDF group_state's (its planning joints left
    out)."""
    if not isinstance(joint_values, str):
        return joint_values or {}
    if srdf is None:
        raise RobotModelError(f"joint_values {joint_values!r} names a group_state: no SRDF")
    state = srdf.state(joint_values)
    return {k: v for k, v in state.values.items() if k not in planning}


def _check_given(
    name: str,
    by_name: Mapping[str, Any],
    planning: list[str],
    followers: Mapping[str, Any],
    *,
    held: Mapping[str, float],
) -> None:
    """RobotModelError unless joint `name` is one whose value can be given (a held joint)."""
    if name not in by_name:
        raise RobotModelError(f"joint_values: unknown joint {name!r}")
    if name in planning:
        raise RobotModelError(
            f"joint_values: {name!r} is a planning joint; its value comes with each state"
        )
    if name in followers:
        raise RobotModelError(
            f"joint_values: {name!r} mimics {followers[name].joint!r}; give that joint"
        )
    if name not in held:
        raise RobotModelError(f"joint_values: {name!r} is a fixed joint")


def _within_limits(name: str, value: float, bounds: tuple[float, float, float] | None) -> float:
    """`value` as a float, or RobotModelError when it is not finite or outside `bounds`."""
    value = float(value)
    if not math.isfinite(value):
        raise RobotModelError(f"joint_values: {name!r} is not finite")
    if bounds is not None and not bounds[0] - 1e-9 <= value <= bounds[1] + 1e-9:
        raise RobotModelError(
            f"joint_values: {name} = {value:.6g} not in [{bounds[0]:.6g}, {bounds[1]:.6g}]"
        )
    return value


def _follow_leaders(values: dict[str, float], pending: dict[str, Any]) -> None:
    """Set each pending mimic joint from its leader's value, leaders first."""
    while pending:
        ready = {n: m for n, m in pending.items() if m.joint in values}
        if not ready:
            raise RobotModelError(f"mimic joints {sorted(pending)} follow each other in a cycle")
        for name, mimic in ready.items():
            multiplier = 1.0 if mimic.multiplier is None else float(mimic.multiplier)
            offset = 0.0 if mimic.offset is None else float(mimic.offset)
            values[name] = multiplier * values[mimic.joint] + offset
            del pending[name]


MAX_MIMIC_MULTIPLIER = 1.0  # a planned mimic joint moves at most as far as its leader


def _check_planned_mimic(by_name: Mapping[str, Any], name: str, mimic: Any) -> None:
    """A joint that mimics a planning joint is followed when both are prismatic (a parallel
    gripper's fingers), |multiplier| ≤ 1 and neither is below the other; else RobotModelError
    names what is not supported."""
    follower, leader = by_name[name], by_name[mimic.joint]
    multiplier = 1.0 if mimic.multiplier is None else float(mimic.multiplier)
    if follower.type != "prismatic" or leader.type != "prismatic":
        raise RobotModelError(
            f"joint {name!r} mimics planning joint {mimic.joint!r}: only prismatic joints that "
            "mimic a prismatic planning joint are supported; hold both (leave them out of the "
            "planning joints)"
        )
    if not abs(multiplier) <= MAX_MIMIC_MULTIPLIER:
        raise RobotModelError(
            f"joint {name!r} mimics {mimic.joint!r} with multiplier {multiplier}: at most "
            f"{MAX_MIMIC_MULTIPLIER} in magnitude is supported for a planning joint"
        )
    parent = {j.child: j for j in by_name.values()}
    for low, high in ((follower, leader), (leader, follower)):
        link = low.parent
        while link in parent:
            if parent[link].name == high.name:
                raise RobotModelError(
                    f"joint {name!r} mimics {mimic.joint!r} on the same chain: not supported"
                )
            link = parent[link].parent


def kinematic_joints(
    ordered: list[Any],
    links: list[str],
    planning: list[str],
    offset: int,
    held: Mapping[str, float],
    limits: Limits,
) -> list[KinematicJoint]:
    """KinematicJoints in topological order; joints outside `planning` are held at `held`."""
    link_index = {name: i for i, name in enumerate(links)}
    result = []
    for joint in ordered:
        if joint.type in ("floating", "planar"):
            raise RobotModelError(
                f"joint {joint.name!r} is {joint.type}, which is not supported "
                "(use base='planar' for a mobile base)"
            )
        origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)
        axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), float)
        norm = float(np.linalg.norm(axis))
        if not np.all(np.isfinite(origin)) or not math.isfinite(norm):
            raise RobotModelError(f"joint {joint.name!r} has a non-finite origin or axis")
        if norm < 1e-12 and joint.type in MOVABLE:
            raise RobotModelError(f"joint {joint.name!r} has a zero axis")
        kind = joint.type if joint.type in MOVABLE else "fixed"
        driver = joint.name
        if kind != "fixed" and joint.mimic is not None and joint.mimic.joint in planning:
            driver = joint.mimic.joint  # follows a planning joint: scaled in kinematics
        index = planning.index(driver) + offset if driver in planning else -1
        bounds = limits.get(joint.name)
        mimic = None
        if kind != "fixed" and joint.mimic is not None:
            multiplier = 1.0 if joint.mimic.multiplier is None else float(joint.mimic.multiplier)
            mimic = (joint.mimic.joint, multiplier, float(joint.mimic.offset or 0.0))
        result.append(
            KinematicJoint(
                name=joint.name,
                kind=kind,
                parent=link_index[joint.parent],
                child=link_index[joint.child],
                origin=origin,
                axis=axis / norm if norm >= 1e-12 else np.array([1.0, 0.0, 0.0]),
                index=index,
                default=held.get(joint.name, 0.0),
                bounds=None if bounds is None else (bounds[0], bounds[1]),
                mimic=mimic,
            )
        )
    return result
