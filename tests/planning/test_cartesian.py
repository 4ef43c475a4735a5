"""Cartesian paths on the Panda without a scene: a straight approach is reached whole and on
its line; no IK, jumps and a rejected motion stop it with MoveIt's fraction."""

from __future__ import annotations

import numpy as np
import pytest

from trajcache.geometry.model.cartesian_bound import deviation_bounds, distance_to_segment
from trajcache.geometry.model.ik import IkProblem, PoseTarget, descend_from_seed
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.pin_kinematics import PinKinematics
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.planning.cartesian import (
    CartesianProblem,
    CartesianStatus,
    MotionVerdict,
    cartesian_path,
    sample_count,
    sample_lines,
)
from trajcache.reference.example_robots import ROBOTS

LINK = "panda_hand"
READY = np.array([0.0, -0.785398, 0.0, -2.35619, 0.0, 1.5707, 0.785398])


@pytest.fixture(scope="module")
def panda() -> PinKinematics:
    robot = ROBOTS["panda"]
    model = load_robot_model(robot.urdf, files=robot.files(), srdf=robot.srdf, group=robot.group)
    return PinKinematics.build(model, robot.urdf)


def _hand(panda: PinKinematics, state: FloatArray) -> FloatArray:
    model = panda.model
    return link_transforms(model, state)[0][model.link_names.index(LINK)]


def _along_axis(panda: PinKinematics, distance: float, *more: float) -> list[FloatArray]:
    """Waypoints `distance` (then `more`) metres along the hand's approach axis (its z)."""
    pose, out, travelled = _hand(panda, READY), [], 0.0
    for step in (distance, *more):
        travelled += step
        waypoint = pose.copy()
        waypoint[:3, 3] += travelled * pose[:3, 2]
        out.append(waypoint)
    return out


def test_a_straight_approach_is_reached_whole_on_its_line(panda: PinKinematics) -> None:
    waypoints = _along_axis(panda, 0.10)
    path = cartesian_path(CartesianProblem(panda, LINK, READY, waypoints))
    assert path.status is CartesianStatus.COMPLETE and path.fraction == 1.0
    assert len(path.states) == 11  # 10 cm in steps of at most 1 cm
    model = panda.model
    origins = link_transforms(model, path.states)[:, model.link_names.index(LINK), :3, 3]
    line = path.lines[0]
    assert distance_to_segment(origins, line[0], line[1]).max() <= 1e-4
    final = _hand(panda, path.states[-1])
    assert np.linalg.norm(final[:3, 3] - waypoints[0][:3, 3]) <= 1e-4
    bounds = deviation_bounds(model, LINK, path.states, path.lines, path.line_of)
    assert bounds.max() < 2e-3  # 1 cm steps: the bound is about a millimetre


def test_samples_respect_both_steps_and_end_on_each_waypoint() -> None:
    start = np.eye(4)
    turned = np.eye(4)
    turned[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]  # 90° about z
    turned[:3, 3] = [0.03, 0.0, 0.0]
    poses, line, share, lines = sample_lines(start, [turned], 0.01, 0.1)
    assert len(poses) == 16  # π/2 / 0.1 rad rounds up to 16 steps, more than 3 of 1 cm
    assert np.allclose(poses[-1], turned) and share[-1] == 1.0 and set(line) == {0}
    assert np.allclose(lines[0], [[0, 0, 0], [0.03, 0, 0]])
    assert sample_count(start, [turned, start], 0.01, 0.1) == 2 * len(poses)


def test_an_unreachable_waypoint_stops_with_moveits_fraction(panda: PinKinematics) -> None:
    waypoints = _along_axis(panda, 0.05, 2.0)  # the second line leaves the arm's reach
    path = cartesian_path(CartesianProblem(panda, LINK, READY, waypoints, max_step=0.05))
    assert path.status is CartesianStatus.NO_IK_SOLUTION
    assert 0.5 <= path.fraction < 1.0  # the first of two lines whole, the second in part
    assert "no IK solution" in path.message


def test_an_absolute_jump_threshold_stops_a_jump(panda: PinKinematics) -> None:
    waypoints = _along_axis(panda, 0.10)
    problem = CartesianProblem(panda, LINK, READY, waypoints, revolute_jump_threshold=1e-3)
    path = cartesian_path(problem)
    assert path.status is CartesianStatus.JOINT_JUMP and path.fraction == 0.0
    assert len(path.states) == 1 and "jumps by" in path.message


def test_the_relative_jump_threshold_cuts_at_the_first_long_step(panda: PinKinematics) -> None:
    waypoints = _along_axis(panda, *[0.001] * 10, 0.01)  # ten 1 mm steps, then one of 1 cm
    problem = CartesianProblem(panda, LINK, READY, waypoints, jump_threshold=2.0)
    path = cartesian_path(problem)
    assert path.status is CartesianStatus.JOINT_JUMP and "mean step" in path.message
    assert len(path.states) == 11 and path.fraction == pytest.approx(10 / 11)


def test_a_rejected_motion_keeps_the_path_before_it(panda: PinKinematics) -> None:
    def validate(states: FloatArray) -> MotionVerdict:
        return MotionVerdict(4, CartesianStatus.COLLISION, "link 'panda_hand' hits 'box'")

    waypoints = _along_axis(panda, 0.10)
    path = cartesian_path(CartesianProblem(panda, LINK, READY, waypoints, validate_fn=validate))
    assert path.status is CartesianStatus.COLLISION and "'box'" in path.message
    assert len(path.states) == 4 and path.fraction == pytest.approx(0.3)


def test_a_warm_start_holds_a_joint_at_its_limit_and_moves_the_others(
    panda: PinKinematics,
) -> None:
    model = panda.model
    seed = READY.copy()
    seed[1] = model.upper[1]  # panda_joint2 at its upper limit
    target = _hand(panda, seed)
    target[:3, 3] += [0.0, 0.01, 0.0]
    goal = PoseTarget(LINK, target, 1e-4, 1e-3)
    assert descend_from_seed(IkProblem(panda, goal, seed, budget_s=1.0)) is None  # it stalls
    held = descend_from_seed(IkProblem(panda, goal, seed, budget_s=1.0, hold_limits=True))
    assert held is not None and np.all(held >= model.lower) and np.all(held <= model.upper)
    assert np.linalg.norm(_hand(panda, held)[:3, 3] - target[:3, 3]) <= 1e-4
