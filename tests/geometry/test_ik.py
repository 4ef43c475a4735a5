"""Inverse kinematics on small seeded problems: reached within tolerance and limits, nearest the
seed, the base held unless allowed, and failures as values."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from trajcache.geometry.model.ik import IkProblem, IkStatus, PoseTarget, _starts, solve_ik
from trajcache.geometry.model.kinematics import check_limits, link_transforms
from trajcache.geometry.model.pin_kinematics import PinKinematics
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.reference.example_robots import ROBOTS
from trajcache.reference.robot import STOWED_ARM, reference_model, reference_urdf

READY = np.array([0.0, -0.785398, 0.0, -2.35619, 0.0, 1.5707, 0.785398])


@pytest.fixture(scope="module")
def panda() -> PinKinematics:
    robot = ROBOTS["panda"]
    model = load_robot_model(robot.urdf, files=robot.files(), srdf=robot.srdf, group=robot.group)
    return PinKinematics.build(model, robot.urdf)


@pytest.fixture(scope="module")
def mobile() -> PinKinematics:
    return PinKinematics.build(reference_model(), reference_urdf())


def _pose(model: RobotModel, state: FloatArray, link: str) -> FloatArray:
    return link_transforms(model, state)[0][model.link_names.index(link)]


def _errors(model: RobotModel, state: FloatArray, target: PoseTarget) -> tuple[float, float]:
    pose = _pose(model, state, target.link)
    position = float(np.linalg.norm(pose[:3, 3] - target.pose[:3, 3]))
    cos = (np.trace(pose[:3, :3].T @ target.pose[:3, :3]) - 1.0) / 2.0
    return position, float(np.arccos(np.clip(cos, -1.0, 1.0)))


def test_random_reachable_poses_are_reached_within_tolerance_and_limits(
    panda: PinKinematics,
) -> None:
    model = panda.model
    rng = np.random.default_rng(11)
    for _ in range(10):
        goal = rng.uniform(model.lower, model.upper)
        target = PoseTarget("panda_hand", _pose(model, goal, "panda_hand"), 1e-3, 1e-2)
        result = solve_ik(IkProblem(panda, target, READY, budget_s=0.5))
        assert result.status is IkStatus.SUCCESS and result.state is not None
        check_limits(model, result.state)
        position, orientation = _errors(model, result.state, target)
        assert position <= 1e-3 and orientation <= 1e-2
        assert result.position_error == pytest.approx(position, abs=1e-9)


def test_the_answer_is_the_solution_nearest_the_seed(panda: PinKinematics) -> None:
    target = PoseTarget("panda_hand", _pose(panda.model, READY, "panda_hand"))
    result = solve_ik(IkProblem(panda, target, READY, solutions=4, budget_s=0.5))
    assert result.status is IkStatus.SUCCESS and result.state is not None
    assert result.solutions == 4
    np.testing.assert_allclose(result.state, READY, atol=1e-9)  # the seed itself solves it


def test_an_unreachable_pose_is_not_found_within_the_budget(panda: PinKinematics) -> None:
    far = np.eye(4)
    far[:3, 3] = (3.0, 0.0, 0.5)
    result = solve_ik(IkProblem(panda, PoseTarget("panda_hand", far), READY, budget_s=0.02))
    assert result.status is IkStatus.NOT_FOUND and result.state is None
    assert result.attempts >= 2


def test_solutions_that_fail_the_validity_predicate_are_in_collision(
    panda: PinKinematics,
) -> None:
    target = PoseTarget("panda_hand", _pose(panda.model, READY, "panda_hand"))
    problem = IkProblem(panda, target, READY, valid_fn=lambda state: False, budget_s=0.02)
    result = solve_ik(problem)
    assert result.status is IkStatus.IN_COLLISION and result.rejected >= 1


def test_a_valid_solution_away_from_an_invalid_seed_solution(panda: PinKinematics) -> None:
    target = PoseTarget("panda_hand", _pose(panda.model, READY, "panda_hand"))

    def valid(state: FloatArray) -> bool:  # the seed's own solution is "in collision"
        return bool(np.abs(state - READY).max() > 0.05)

    result = solve_ik(IkProblem(panda, target, READY, valid_fn=valid, budget_s=0.5))
    assert result.status is IkStatus.SUCCESS and result.state is not None
    assert valid(result.state) and result.rejected >= 1


def test_a_planar_base_stays_unless_it_may_move(mobile: PinKinematics) -> None:
    model = mobile.model
    seed = np.array([1.0, -0.5, 0.3, *STOWED_ARM])
    goal = seed.copy()
    goal[:3] = (2.2, 0.4, 1.2)  # out of the arm's reach from the seed's base
    target = PoseTarget("tool_tip", _pose(model, goal, "tool_tip"))
    held = solve_ik(IkProblem(mobile, target, seed, budget_s=0.05))
    assert held.status is IkStatus.NOT_FOUND
    moved = solve_ik(IkProblem(mobile, target, seed, move_base=True, budget_s=0.5))
    assert moved.status is IkStatus.SUCCESS and moved.state is not None
    position, orientation = _errors(model, moved.state, target)
    assert position <= 1e-3 and orientation <= 1e-2
    assert not np.allclose(moved.state[:2], seed[:2])
    reach = mobile.model.arm_offset
    nearby = goal.copy()
    nearby[reach:] = STOWED_ARM
    nearby[reach] += 0.3  # a reachable pose with the base held
    target = PoseTarget("tool_tip", _pose(model, np.r_[seed[:3], nearby[reach:]], "tool_tip"))
    arm = solve_ik(IkProblem(mobile, target, seed, budget_s=0.5))
    assert arm.status is IkStatus.SUCCESS and arm.state is not None
    np.testing.assert_array_equal(arm.state[:3], seed[:3])


def test_given_starts_are_tried_after_the_seed(panda: PinKinematics) -> None:
    goal = READY + 0.4
    target = PoseTarget("panda_hand", _pose(panda.model, goal, "panda_hand"))
    result = solve_ik(IkProblem(panda, target, READY, starts=[goal], solutions=2, budget_s=0.5))
    assert result.status is IkStatus.SUCCESS
    assert result.attempts >= 2


def test_restarts_stay_within_the_window_about_the_seed(panda: PinKinematics) -> None:
    """A pose goal looks near a cached end first: with `window`, every random restart lies
    within it of the seed's values (and in the limits); without, they spread to the range."""
    target = PoseTarget("panda_hand", _pose(panda.model, READY, "panda_hand"))
    model = panda.model

    def restarts(window: float | None) -> FloatArray:
        problem = IkProblem(panda, target, READY, window=window)
        drawn = itertools.islice(_starts(problem, np.random.default_rng(0)), 1, 41)
        return np.array(list(drawn))

    near = restarts(0.3)
    assert np.abs(near - READY).max() <= 0.3 + 1e-12
    assert (near >= model.lower).all() and (near <= model.upper).all()
    assert np.abs(restarts(None) - READY).max() > 1.0
