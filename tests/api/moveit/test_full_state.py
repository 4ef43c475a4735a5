"""A MotionPlanRequest as MoveIt clients send it: full robot states, lists, unknown planners,
budgets and bounds read as MoveIt reads them. Small models, no database, no server."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from tests.robots import Y_AXIS, box, collision, joint, link, two_joint_arm
from trajcache.api.moveit import (
    MotionPlanError,
    MotionPlanQuery,
    MotionPlanRequestIn,
    MoveItErrorCode,
    motion_plan_query,
)
from trajcache.core.config import Settings
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.urdf import load_robot_model

SETTINGS = Settings.model_construct()
# The pincer arm with a second held finger (`thumb`) and a tool fixed to the forearm.
_HAND = two_joint_arm(name="hand", finger=True).replace(
    "</robot>",
    link("thumb", collision(box(0.01, 0.01, 0.04)))
    + link("tool")
    + joint("thumb", "prismatic", "fore", "thumb", xyz=(0, 0, 0.2), axis=Y_AXIS, limit=(0, 0.04))
    + joint("tool_joint", "fixed", "fore", "tool", xyz=(0, 0, 0.25))
    + "</robot>",
)
HAND = load_robot_model(_HAND, joint_names=["shoulder", "elbow"])
ARM = load_robot_model(two_joint_arm())
PLANAR = load_robot_model(two_joint_arm(), base="planar")
GOAL = {"shoulder": 1.0, "elbow": 0.5}


def _goal(tolerance: float = 0.0, **positions: float) -> list[dict[str, Any]]:
    return [
        {"joint_name": n, "position": v, "tolerance_above": tolerance, "tolerance_below": tolerance}
        for n, v in positions.items()
    ]


def _message(
    start: dict[str, float], goal: list[dict[str, Any]] | None = None, **fields: Any
) -> Any:
    body = {
        "start_state": {"joint_state": {"name": list(start), "position": list(start.values())}},
        "goal_constraints": [{"joint_constraints": goal if goal is not None else _goal(**GOAL)}],
        **fields,
    }
    return MotionPlanRequestIn.model_validate(body)


def _query(model: RobotModel, message: Any) -> MotionPlanQuery:
    return motion_plan_query(message, model=model, settings=SETTINGS)


def _refusal(model: RobotModel, message: Any) -> MotionPlanError:
    with pytest.raises(MotionPlanError) as caught:
        _query(model, message)
    return caught.value


def _warned(query: MotionPlanQuery, *needles: str) -> str:
    hits = [w for w in query.warnings if all(n in w for n in needles)]
    assert hits, f"no warning with {needles} in {query.warnings}"
    return hits[0]


def test_an_unknown_planner_id_falls_back_to_the_default_with_a_warning() -> None:
    query = _query(ARM, _message({"shoulder": 0.0, "elbow": 0.0}, planner_id="BKPIECEGood"))
    assert query.request.planner == SETTINGS.default_planner
    _warned(query, "'BKPIECEGood'", repr(SETTINGS.default_planner))
    # no guessing by prefix: LBKPIECE1 is not KPIECE1
    lbkpiece = _query(ARM, _message({"shoulder": 0.0, "elbow": 0.0}, planner_id="LBKPIECE1"))
    assert lbkpiece.request.planner == SETTINGS.default_planner
    _warned(lbkpiece, "'LBKPIECE1'")
    for known, native in [("RRTConnectkConfigDefault", SETTINGS.default_planner),
                          ("RRTConnect", SETTINGS.default_planner), ("KPIECE1", "kpiece"),
                          ("rrtconnect", "rrtconnect")]:  # fmt: skip
        query = _query(ARM, _message({"shoulder": 0.0, "elbow": 0.0}, planner_id=known))
        assert query.request.planner == native
        assert not any("planner_id" in w for w in query.warnings)


def test_a_planning_time_above_the_maximum_is_clamped_with_a_warning() -> None:
    query = _query(ARM, _message({"shoulder": 0.0, "elbow": 0.0}, allowed_planning_time=60.0))
    assert query.request.budget_s == SETTINGS.plan_budget_max_s
    _warned(query, "allowed_planning_time 60", f"plan_budget_max_s={SETTINGS.plan_budget_max_s:g}")
    within = _query(ARM, _message({"shoulder": 0.0, "elbow": 0.0}, allowed_planning_time=2.0))
    assert within.request.budget_s == 2.0
    assert not any("allowed_planning_time" in w for w in within.warnings)


def _multi_dof(translation: Any, rotation: Any, **joints: float) -> Any:
    return MotionPlanRequestIn.model_validate(
        {
            "start_state": {
                "joint_state": {"name": list(joints), "position": list(joints.values())},
                "multi_dof_joint_state": {
                    "joint_names": ["virtual_joint"],
                    "transforms": [{"translation": translation, "rotation": rotation}],
                    "twist": [],
                    "wrench": [],
                },
            },
            "goal_constraints": [{"joint_constraints": _goal(**GOAL)}],
        }
    )


def test_vectors_and_quaternions_may_be_lists() -> None:
    yaw = 0.5
    rotation = [0, 0, math.sin(yaw / 2), math.cos(yaw / 2)]
    planar = _query(PLANAR, _multi_dof([2, -1, 0], rotation, shoulder=0.0, elbow=0.0))
    np.testing.assert_allclose(planar.start, [2.0, -1.0, yaw, 0.0, 0.0])
    as_maps = dict(zip("xyzw", rotation, strict=True))
    same = _query(PLANAR, _multi_dof({"x": 2, "y": -1}, as_maps, shoulder=0.0, elbow=0.0))
    np.testing.assert_allclose(same.start, planar.start)
    fixed = _query(ARM, _multi_dof([0, 0, 0], [0, 0, 0, 1], shoulder=0.0, elbow=0.0))
    _warned(fixed, "multi_dof_joint_state is ignored", "fixed")
    with pytest.raises(ValueError, match=r"4 values \(x, y, z, w\), got 3"):
        _multi_dof([0, 0, 0], [0, 0, 1], shoulder=0.0, elbow=0.0)


def test_a_full_state_is_read_and_every_disagreeing_held_joint_is_named() -> None:
    full = {"shoulder": 0.1, "elbow": 0.2, "finger": 0.0005, "thumb": 0.0, "tool_joint": 0.7}
    query = _query(HAND, _message(full))
    np.testing.assert_array_equal(query.start, [0.1, 0.2])  # finger within the 1e-3 tolerance
    refusal = _refusal(HAND, _message({**full, "finger": 0.02, "thumb": 0.03}))
    assert refusal.code is MoveItErrorCode.INVALID_ROBOT_STATE
    assert "finger = 0.02, held at 0" in str(refusal) and "thumb = 0.03, held at 0" in str(refusal)
    # the robot's own held values count, not only the model's
    held = motion_plan_query(
        _message({**full, "finger": 0.02}), model=HAND, settings=SETTINGS, held={"finger": 0.02}
    )
    np.testing.assert_array_equal(held.start, [0.1, 0.2])


def test_fixed_joints_are_ignored_with_a_warning_and_unknown_joints_all_named() -> None:
    query = _query(HAND, _message({"shoulder": 0.0, "elbow": 0.0, "tool_joint": 3.0}))
    _warned(query, "fixed joints tool_joint", "ignored")
    goal = _goal(**GOAL, tool_joint=1.0)
    in_goal = _query(HAND, _message({"shoulder": 0.0, "elbow": 0.0}, goal))
    _warned(in_goal, "goal_constraints[0]", "tool_joint")
    unknown = _refusal(HAND, _message({"shoulder": 0.0, "elbow": 0.0, "ghost": 1, "wheel": 2}))
    assert unknown.code is MoveItErrorCode.INVALID_ROBOT_STATE
    assert "'ghost', 'wheel'" in str(unknown)
    goal_unknown = _refusal(HAND, _message({"shoulder": 0.0, "elbow": 0.0}, _goal(
        **GOAL, ghost=0.0, wheel=0.0)))  # fmt: skip
    assert goal_unknown.code is MoveItErrorCode.INVALID_GOAL_CONSTRAINTS
    assert "'ghost', 'wheel'" in str(goal_unknown)


def test_a_start_just_outside_its_limits_is_clamped_as_moveit_does() -> None:
    query = _query(ARM, _message({"shoulder": 2.04, "elbow": -1.5000026}))
    np.testing.assert_array_equal(query.start, [2.0, -1.5])
    assert query.request.start == {"shoulder": 2.0, "elbow": -1.5}
    _warned(query, "shoulder = 2.04 > 2 (upper limit), by 0.04", "start_state_max_bounds_error")
    _warned(query, "elbow = -1.5000026 < -1.5 (lower limit), by 2.6e-06")
    refusal = _refusal(ARM, _message({"shoulder": 2.06, "elbow": -1.6}))
    assert refusal.code is MoveItErrorCode.INVALID_ROBOT_STATE
    text = str(refusal)
    assert "shoulder = 2.06 > 2 (upper limit), by 0.06" in text
    assert "elbow = -1.6 < -1.5 (lower limit), by 0.1" in text


def test_a_goal_is_clamped_within_its_tolerances_and_refused_beyond() -> None:
    goal = _goal(tolerance=0.02, shoulder=2.01, elbow=0.5)
    query = _query(ARM, _message({"shoulder": 0.0, "elbow": 0.0}, goal))
    assert query.request.goal == {"shoulder": 2.0, "elbow": 0.5}
    _warned(query, "goal_constraints[0]", "shoulder = 2.01 > 2 (upper limit)", "tolerances")
    exact = _refusal(ARM, _message({"shoulder": 0.0, "elbow": 0.0}, _goal(
        shoulder=1.0, elbow=-1.5000026)))  # fmt: skip
    assert exact.code is MoveItErrorCode.INVALID_GOAL_CONSTRAINTS
    assert "elbow = -1.5000026 < -1.5 (lower limit), by 2.6e-06" in str(exact)
