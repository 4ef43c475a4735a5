"""The MotionPlanResponse of an answer (or of a refusal), as rosbridge-style dicts.

The planning joints are the `joint_trajectory`; a planar base is the `multi_dof_joint_trajectory`
(one joint: translation x, y; a rotation about z; velocities and accelerations as world-frame
twists). Times are `{sec, nanosec}` and strictly increase: of two points less than a nanosecond
apart, the later one stands.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

from trajcache.api.answer_extras import extras_body
from trajcache.api.moveit._codes import MoveItErrorCode, answer_code
from trajcache.api.moveit._messages import MotionPlanRequestIn
from trajcache.api.moveit._request import MotionPlanQuery
from trajcache.geometry.model.robot import RobotModel
from trajcache.services.plan.flow import PlanAnswer

SOURCE = "trajcache"
_NS = 1_000_000_000


def answered_body(
    *,
    message: MotionPlanRequestIn,
    query: MotionPlanQuery,
    model: RobotModel,
    answer: PlanAnswer,
    began: float,
) -> dict[str, Any]:
    """The response to a request the plan flow answered, for the robot's `model`."""
    extras = extras_body(answer.details)
    start = answer.states[0] if answer.states is not None else query.start
    code = answer_code(answer)
    return _body(
        message,
        trajectory_start=robot_state_body(model, list(map(float, start)), query.base_joint),
        trajectory=robot_trajectory_body(model, extras["joint_trajectory"], query.base_joint),
        code=code,
        text="" if code is MoveItErrorCode.SUCCESS else answer.message,
        warnings=[*query.warnings, *answer.warnings],
        trajcache={
            "status": answer.status.value,
            "source": answer.source.value if answer.source else None,
            "trajectory_id": answer.trajectory_id,
            "candidates_tried": answer.candidates_tried,
            "timings_ms": answer.timings_ms,
            "message": answer.message,
            "rejected": [
                {"trajectory_id": r["trajectory_id"], "status": r["status"], "reason": r["reason"]}
                for r in answer.rejected
            ],
            "quality": extras["quality"],
        },
        began=began,
    )


def refused_body(
    *,
    message: MotionPlanRequestIn,
    code: MoveItErrorCode,
    text: str,
    began: float,
    warnings: Sequence[str] = (),
) -> dict[str, Any]:
    """The response to a request refused before planning: its start state echoed, no path."""
    multi_dof = message.start_state.multi_dof_joint_state
    transforms = [multi_dof.planar(k) for k in range(len(multi_dof.joint_names))]
    trajectory_start = {
        "joint_state": {
            "name": list(message.start_state.joint_state.name),
            "position": list(message.start_state.joint_state.position),
        },
        "multi_dof_joint_state": {
            "joint_names": list(multi_dof.joint_names),
            "transforms": [
                {"translation": t.model_dump(), "rotation": r.model_dump()} for t, r in transforms
            ],
        },
    }
    elapsed_ms = (time.perf_counter() - began) * 1e3
    return _body(
        message,
        trajectory_start=trajectory_start,
        trajectory=robot_trajectory_body(None, None, ""),
        code=code,
        text=text,
        warnings=list(warnings),
        trajcache={
            "status": "invalid",
            "source": None,
            "trajectory_id": None,
            "candidates_tried": 0,
            "timings_ms": {"total": round(elapsed_ms, 3)},
            "message": text,
            "rejected": [],
            "quality": None,
        },
        began=began,
    )


def _body(
    message: MotionPlanRequestIn,
    *,
    trajectory_start: dict[str, Any],
    trajectory: dict[str, Any],
    code: MoveItErrorCode,
    text: str,
    warnings: list[str],
    trajcache: dict[str, Any],
    began: float,
) -> dict[str, Any]:
    return {
        "trajectory_start": trajectory_start,
        "group_name": message.group_name,
        "trajectory": trajectory,
        "planning_time": round(time.perf_counter() - began, 6),
        "error_code": {"val": int(code), "message": text, "source": SOURCE},
        "warnings": warnings,
        "trajcache": trajcache,
    }


def robot_state_body(model: RobotModel, state: list[float], base_joint: str) -> dict[str, Any]:
    """A `moveit_msgs/RobotState` of a state: the planning joints, and the planar base as the
    multi-DOF joint `base_joint`."""
    offset = model.arm_offset
    return {
        "joint_state": {"name": list(model.joint_names), "position": state[offset:]},
        "multi_dof_joint_state": {
            "joint_names": [base_joint] if offset else [],
            "transforms": [_transform(state[:3])] if offset else [],
        },
    }


def robot_trajectory_body(
    model: RobotModel | None, timed: dict[str, Any] | None, base_joint: str
) -> dict[str, Any]:
    """The RobotTrajectory of a timed `joint_trajectory` (all state values); empty if None."""
    arm: dict[str, Any] = {"joint_names": [], "points": []}
    base: dict[str, Any] = {"joint_names": [], "points": []}
    if model is None or timed is None:
        return {"joint_trajectory": arm, "multi_dof_joint_trajectory": base}
    offset = model.arm_offset
    arm["joint_names"] = list(model.joint_names)
    if offset:
        base["joint_names"] = [base_joint]
    for stamp, point in _stamped(timed["points"]):
        q, v, a = point["positions"], point["velocities"], point["accelerations"]
        arm["points"].append(
            {
                "positions": q[offset:],
                "velocities": v[offset:],
                "accelerations": a[offset:],
                "time_from_start": stamp,
            }
        )
        if offset:
            base["points"].append(
                {
                    "transforms": [_transform(q[:3])],
                    "velocities": [_twist(v[:3])],
                    "accelerations": [_twist(a[:3])],
                    "time_from_start": stamp,
                }
            )
    return {"joint_trajectory": arm, "multi_dof_joint_trajectory": base}


def _stamped(points: Sequence[dict[str, Any]]) -> list[tuple[dict[str, int], dict[str, Any]]]:
    """Each point with its `{sec, nanosec}`, times strictly increasing."""
    kept: list[tuple[int, dict[str, Any]]] = []
    for point in points:
        ns = round(point["time_from_start"] * _NS)
        if kept and ns <= kept[-1][0]:
            kept.pop()  # within a nanosecond of the previous point: the later one stands
        kept.append((ns, point))
    return [({"sec": ns // _NS, "nanosec": ns % _NS}, point) for ns, point in kept]


def _transform(pose: Sequence[float]) -> dict[str, Any]:
    x, y, theta = pose
    return {
        "translation": {"x": x, "y": y, "z": 0.0},
        "rotation": {"x": 0.0, "y": 0.0, "z": math.sin(theta / 2), "w": math.cos(theta / 2)},
    }


def _twist(rates: Sequence[float]) -> dict[str, Any]:
    x, y, theta = rates
    return {"linear": {"x": x, "y": y, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": theta}}
