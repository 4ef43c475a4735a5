"""The bound on a link origin's distance from its Cartesian line between two joint samples,
checked against forward kinematics at many intermediate points of random Panda motions."""

from __future__ import annotations

import numpy as np
import pytest

from trajcache.geometry.model.cartesian_bound import (
    chain_weights,
    deviation_bounds,
    distance_to_segment,
)
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.reference.example_robots import ROBOTS

LINK = "panda_hand"


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    robot = ROBOTS["panda"]
    return load_robot_model(robot.urdf, files=robot.files(), srdf=robot.srdf, group=robot.group)


def _origins(model: RobotModel, states: FloatArray) -> FloatArray:
    return link_transforms(model, states)[:, model.link_names.index(LINK), :3, 3]


def test_the_chain_weights_count_every_arm_joint_and_a_positive_reach(panda: RobotModel) -> None:
    weights = chain_weights(panda, LINK)
    assert weights.revolute.tolist() == [1.0] * 7
    assert not weights.prismatic.any()
    assert 0.8 < weights.reach < 1.5  # the Panda's offsets from joint 1 to the hand


@pytest.mark.parametrize("size", [0.005, 0.05, 0.3, 1.0])
def test_the_bound_is_never_exceeded_on_random_motions(panda: RobotModel, size: float) -> None:
    rng = np.random.default_rng(int(size * 1000))
    t = np.linspace(0.0, 1.0, 101)
    worst = 0.0
    for _ in range(40):
        a = rng.uniform(panda.lower, panda.upper)
        b = np.clip(a + rng.uniform(-size, size, panda.dof), panda.lower, panda.upper)
        ends = _origins(panda, np.stack([a, b]))
        # a line near the chord, its ends up to 2 mm from the samples' origins
        line = (ends + rng.uniform(-2e-3, 2e-3, (2, 3)))[None]
        bound = deviation_bounds(panda, LINK, np.stack([a, b]), line, np.zeros(2, dtype=int))
        inside = _origins(panda, a + t[:, None] * (b - a))
        distance = distance_to_segment(inside, line[0, 0], line[0, 1])
        assert distance.max() <= bound[0] + 1e-12
        worst = max(worst, float(distance.max() / bound[0]))
    assert worst > 0.01  # not vacuous: the bound is within two orders of the deviation


def test_the_bound_of_a_chord_shrinks_with_the_square_of_the_step(panda: RobotModel) -> None:
    a = np.array([0.0, -0.785398, 0.0, -2.35619, 0.0, 1.5707, 0.785398])
    bounds = []
    for step in (0.01, 0.005):
        states = np.stack([a, a + step])
        chord = _origins(panda, states)[None]  # the line through both ends: no end distance
        bounds.append(deviation_bounds(panda, LINK, states, chord, np.zeros(2, dtype=int))[0])
    assert bounds[0] < 2e-3 and bounds[1] == pytest.approx(bounds[0] / 4)


def test_distance_to_a_segment_is_to_its_nearest_point() -> None:
    a, b = np.zeros(3), np.array([1.0, 0.0, 0.0])
    points = np.array([[0.5, 1.0, 0.0], [-1.0, 0.0, 0.0], [2.0, 0.0, 2.0]])
    assert distance_to_segment(points, a, b) == pytest.approx([1.0, 1.0, 5**0.5])
