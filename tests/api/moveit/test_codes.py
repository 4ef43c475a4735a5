"""MoveIt error codes of native plan outcomes, and planner ids: pure functions, no database."""

from __future__ import annotations

import pytest

from trajcache.api.moveit import MoveItErrorCode, answer_code, native_planner, state_error_code
from trajcache.core.planners import PLANNER_NAMES
from trajcache.geometry.errors import CollisionStateError, StateError
from trajcache.services.plan.flow import PlanAnswer, PlanStatus

C = MoveItErrorCode


def _answer(status: PlanStatus, message: str = "") -> PlanAnswer:
    return PlanAnswer(status, None, None, None, 0, {}, message)


def test_codes_are_moveit_msgs_values() -> None:
    assert (C.SUCCESS, C.PLANNING_FAILED, C.INVALID_MOTION_PLAN, C.TIMED_OUT) == (1, -1, -2, -6)
    assert (C.START_STATE_IN_COLLISION, C.GOAL_IN_COLLISION) == (-10, -12)
    assert (C.INVALID_GOAL_CONSTRAINTS, C.INVALID_ROBOT_STATE, C.FAILURE) == (-16, -17, 99999)


@pytest.mark.parametrize(
    ("status", "message", "code"),
    [
        (PlanStatus.SUCCESS, "", C.SUCCESS),
        (PlanStatus.MISS, "no valid cached trajectory; planning is off", C.PLANNING_FAILED),
        (PlanStatus.FAILURE, "timeout: no path within 0.5 s", C.TIMED_OUT),
        (PlanStatus.FAILURE, "timeout: x (negative cache: this query failed 1 s ago)", C.TIMED_OUT),
        (PlanStatus.FAILURE, "invalid_start: start is in collision: a", C.START_STATE_IN_COLLISION),
        (PlanStatus.FAILURE, "invalid_goal: goal is within 0.1 mm", C.GOAL_IN_COLLISION),
        (PlanStatus.FAILURE, "planned path failed validation: hit", C.INVALID_MOTION_PLAN),
        (PlanStatus.FAILURE, "solved: but no path", C.PLANNING_FAILED),
        (PlanStatus.FAILURE, "something else", C.PLANNING_FAILED),
        (PlanStatus.ERROR, "error: backend down", C.FAILURE),
    ],
)
def test_answer_codes(status: PlanStatus, message: str, code: MoveItErrorCode) -> None:
    assert answer_code(_answer(status, message)) is code


def test_state_error_codes_follow_the_state_named_first() -> None:
    assert state_error_code(CollisionStateError("start state is in collision: x")) is (
        C.START_STATE_IN_COLLISION
    )
    assert state_error_code(CollisionStateError("goal state is in collision: x")) is (
        C.GOAL_IN_COLLISION
    )
    assert state_error_code(StateError("goal is out of joint limits")) is C.INVALID_GOAL_CONSTRAINTS
    assert state_error_code(StateError("start lacks elbow")) is C.INVALID_ROBOT_STATE


@pytest.mark.parametrize(
    ("planner_id", "native"),
    [
        ("", ""),
        ("RRTConnect", ""),  # MoveIt's RRTConnect ids: the service's default planner
        ("RRTConnectkConfigDefault", ""),
        ("geometric::RRTConnect", ""),
        ("rrtconnect", "rrtconnect"),  # the native name: OMPL's RRTConnect
        ("BITstar", "bitstar"),
        ("geometric::BITstarkConfigDefault", "bitstar"),
        ("BIT*", "bitstar"),
        ("PRMkConfigDefault", "prm"),
        ("KPIECE1", "kpiece"),
        ("RRT", "rrt"),
        (" RRIS ", "rris"),
    ],
)
def test_planner_ids(planner_id: str, native: str) -> None:
    assert native_planner(planner_id) == native
    assert native == "" or native in PLANNER_NAMES


@pytest.mark.parametrize("planner_id", ["CHOMP", "RRTstar", "LBKPIECE1", "geometric::"])
def test_unknown_planner_ids_name_the_known_ones(planner_id: str) -> None:
    with pytest.raises(ValueError, match=r"rrtconnect.*RRTConnectkConfigDefault"):
        native_planner(planner_id)
