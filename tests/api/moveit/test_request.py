"""A MotionPlanRequest read against a model: small models, no database, no server."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from tests.robots import TWO_JOINT_URDF
from trajcache.api.moveit import (
    MotionPlanError,
    MotionPlanRequestIn,
    MoveItErrorCode,
    motion_plan_query,
)
from trajcache.core.config import Settings
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.urdf import load_robot_model

SETTINGS = Settings.model_construct()
ARM = load_robot_model(TWO_JOINT_URDF)
SHOULDER_ONLY = load_robot_model(TWO_JOINT_URDF, joint_names=["shoulder"])  # elbow held at 0
PLANAR = load_robot_model(TWO_JOINT_URDF, base="planar")


def _joints(**positions: float) -> list[dict[str, Any]]:
    return [{"joint_name": n, "position": v} for n, v in positions.items()]


def _message(start: dict[str, float], goal: list[dict[str, Any]], **fields: Any) -> Any:
    body = {
        "start_state": {"joint_state": {"name": list(start), "position": list(start.values())}},
        "goal_constraints": [{"joint_constraints": goal}],
        **fields,
    }
    return MotionPlanRequestIn.model_validate(body)


def _refusal(model: RobotModel, message: Any) -> MotionPlanError:
    with pytest.raises(MotionPlanError) as caught:
        motion_plan_query(message, model=model, settings=SETTINGS)
    return caught.value


def test_defaults_come_from_the_settings_and_scaling_zero_is_one() -> None:
    query = motion_plan_query(
        _message({"shoulder": 0.0, "elbow": 0.0}, _joints(shoulder=1.0, elbow=0.5)),
        model=ARM,
        settings=SETTINGS,
    )
    request = query.request
    assert request.start == {"shoulder": 0.0, "elbow": 0.0}
    assert request.goal == {"shoulder": 1.0, "elbow": 0.5}
    assert (request.budget_s, request.planner) == (SETTINGS.plan_budget_s, SETTINGS.default_planner)
    assert (request.threshold, request.fallback, request.lookup) == (0.2, True, True)
    assert (query.timing.velocity_scaling, query.timing.acceleration_scaling) == (1.0, 1.0)
    assert query.timing.method == "toppra"
    np.testing.assert_array_equal(query.start, [0.0, 0.0])


def test_budget_planner_and_scaling_are_taken() -> None:
    message = _message(
        {"shoulder": 0.0, "elbow": 0.0},
        _joints(shoulder=1.0, elbow=0.5),
        allowed_planning_time=4.5,
        planner_id="BITstarkConfigDefault",
        max_velocity_scaling_factor=0.25,
        max_acceleration_scaling_factor=0.5,
    )
    query = motion_plan_query(message, model=ARM, settings=SETTINGS)
    assert (query.request.budget_s, query.request.planner) == (4.5, "bitstar")
    assert (query.timing.velocity_scaling, query.timing.acceleration_scaling) == (0.25, 0.5)
    too_long = message.model_copy(update={"allowed_planning_time": 31.0})
    clamped = motion_plan_query(too_long, model=ARM, settings=SETTINGS)
    assert clamped.request.budget_s == 30.0  # plan_budget_max_s, with a warning
    assert any("plan_budget_max_s=30" in w for w in clamped.warnings)


def test_held_joints_must_sit_at_their_held_values() -> None:
    goal = _joints(shoulder=1.0, elbow=0.05)
    ok = _message({"shoulder": 0.0, "elbow": 0.0}, [*goal[:1], {**goal[1], "tolerance_below": 0.1}])
    query = motion_plan_query(ok, model=SHOULDER_ONLY, settings=SETTINGS)
    assert query.request.goal == {"shoulder": 1.0}
    off_goal = _refusal(SHOULDER_ONLY, _message({"shoulder": 0.0, "elbow": 0.0}, goal))
    assert off_goal.code is MoveItErrorCode.INVALID_GOAL_CONSTRAINTS
    assert "holds it at 0" in str(off_goal)
    off_start = _refusal(SHOULDER_ONLY, _message({"shoulder": 0.0, "elbow": 0.3}, goal[:1]))
    assert off_start.code is MoveItErrorCode.INVALID_ROBOT_STATE and "elbow" in str(off_start)


def test_the_first_goal_covering_every_joint_is_taken() -> None:
    message = MotionPlanRequestIn.model_validate(
        {
            "start_state": {"joint_state": {"name": ["shoulder", "elbow"], "position": [0, 0]}},
            "goal_constraints": [
                {"position_constraints": [{"link_name": "fore"}]},
                {"joint_constraints": _joints(shoulder=0.3)},
                {"joint_constraints": _joints(shoulder=0.4, elbow=0.1)},
                {"joint_constraints": _joints(shoulder=0.5, elbow=0.2)},
            ],
        }
    )
    query = motion_plan_query(message, model=ARM, settings=SETTINGS)
    assert query.request.goal == {"shoulder": 0.4, "elbow": 0.1}


def test_same_joint_at_two_goal_positions_is_refused() -> None:
    goal = [*_joints(shoulder=1.0, elbow=0.5), *_joints(shoulder=0.9)]
    refusal = _refusal(ARM, _message({"shoulder": 0.0, "elbow": 0.0}, goal))
    assert refusal.code is MoveItErrorCode.INVALID_GOAL_CONSTRAINTS and "two positions" in str(
        refusal
    )


def _planar_message(rotation: dict[str, float], goal: list[dict[str, Any]]) -> Any:
    return MotionPlanRequestIn.model_validate(
        {
            "start_state": {
                "joint_state": {"name": ["shoulder", "elbow"], "position": [0.0, 0.0]},
                "multi_dof_joint_state": {
                    "joint_names": ["odom_joint"],
                    "poses": [{"position": {"x": 2.0, "y": -1.0}, "orientation": rotation}],
                },
            },
            "goal_constraints": [{"joint_constraints": goal}],
        }
    )


def test_planar_start_from_the_multi_dof_pose_and_goal_from_base_variables() -> None:
    yaw = 2.5
    rotation = {"z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}
    goal = _joints(**{"base_x": 3.0, "odom_joint/y": -1.5, "shoulder": 1.0, "elbow": 0.5})
    query = motion_plan_query(_planar_message(rotation, goal), model=PLANAR, settings=SETTINGS)
    np.testing.assert_allclose(query.start, [2.0, -1.0, yaw, 0.0, 0.0])
    # base_theta is free in the goal: it stays at the start's yaw
    assert query.request.goal == pytest.approx(
        {"base_x": 3.0, "base_y": -1.5, "base_theta": yaw, "shoulder": 1.0, "elbow": 0.5}
    )
    assert query.base_joint == "odom_joint"
    zero = motion_plan_query(
        _planar_message({"w": 0.0}, goal), model=PLANAR, settings=SETTINGS
    )  # an all-zero quaternion (a ROS 1 default) is the identity
    assert zero.start[2] == 0.0


def test_a_tilted_or_unnormalized_base_is_an_invalid_start() -> None:
    goal = _joints(shoulder=1.0, elbow=0.5)
    tilted = _refusal(PLANAR, _planar_message({"x": math.sin(0.1), "w": math.cos(0.1)}, goal))
    assert tilted.code is MoveItErrorCode.INVALID_ROBOT_STATE and "tilted" in str(tilted)
    scaled = _refusal(PLANAR, _planar_message({"w": 2.0}, goal))
    assert scaled.code is MoveItErrorCode.INVALID_ROBOT_STATE and "unit quaternion" in str(scaled)


def test_base_variables_of_a_fixed_base_are_unknown_joints() -> None:
    goal = _joints(shoulder=1.0, elbow=0.5, base_x=1.0)
    refusal = _refusal(ARM, _message({"shoulder": 0.0, "elbow": 0.0}, goal))
    assert refusal.code is MoveItErrorCode.INVALID_GOAL_CONSTRAINTS and "'base_x'" in str(refusal)
