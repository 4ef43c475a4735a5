"""The real-robot benchmark's generator and its dense check (Pinocchio, coal), on the Panda."""

from __future__ import annotations

import numpy as np
import pytest

from dense_mesh import MeshChecker
from robot_description import describe
from scene_families import FAMILIES, generate_problem, workspace
from trajcache.reference.example_robots import ROBOTS

HAND_IN_LINK5 = [0.0, 0.0, 0.0, -1.5, 0.0, -0.0175, 0.0]  # joint 6 at its lower limit


@pytest.fixture(scope="module")
def panda() -> MeshChecker:
    return MeshChecker(describe(ROBOTS["panda"]))


@pytest.fixture(scope="module")
def panda_without_srdf() -> MeshChecker:
    return MeshChecker(describe(ROBOTS["panda"], srdf=False))


def test_the_hand_folded_into_link5_is_a_self_collision_only_without_the_srdf(
    panda: MeshChecker, panda_without_srdf: MeshChecker
) -> None:
    own, scene, _ = panda_without_srdf.contacts(HAND_IN_LINK5)
    assert "panda_link5–panda_hand" in own and not scene
    assert panda.is_free(HAND_IN_LINK5)  # the SRDF disables panda_hand–panda_link5


def test_held_fingers_are_one_body_with_the_hand_and_the_mimic_follows(
    panda_without_srdf: MeshChecker,
) -> None:
    checker = MeshChecker(describe(ROBOTS["panda"], held={"panda_finger_joint1": 0.03}))
    q = checker.configuration(np.zeros(7))
    model = checker.model
    for name in ("panda_finger_joint1", "panda_finger_joint2"):
        assert q[model.joints[model.getJointId(name)].idx_q] == pytest.approx(0.03)
    # Closed fingers touch each other, but no planning joint moves one against the other.
    home = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
    assert panda_without_srdf.contacts(home)[0] == []


def test_interpolation_is_four_times_finer_than_the_paper(panda: MeshChecker) -> None:
    start = np.array([0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0])
    goal = start + np.array([0.35, 0.0, 0.0, 0.0, 0.0, 0.0, -0.1])
    dense = panda.interpolate(np.stack([start, goal]))
    assert len(dense) == 41  # 0.35 rad in steps of 0.00875 rad
    assert np.abs(np.diff(dense, axis=0)).max() <= 0.00875 + 1e-12
    np.testing.assert_allclose(dense[[0, -1]], np.stack([start, goal]))


@pytest.mark.parametrize("family", FAMILIES)
def test_generated_starts_and_goals_are_free(panda: MeshChecker, family: str) -> None:
    ws = workspace(panda, seed=0)
    assert 0.8 < ws.reach < 1.1  # the Panda reaches about 0.85 m past its shoulder, plus the hand
    problem = generate_problem(panda, ws, family, 0, seed=3)
    assert problem is not None and problem.objects
    panda.set_scene(problem.objects)
    for state in (problem.start, problem.goal):
        assert panda.within_limits(state).all()
        assert panda.contacts(state) == ([], [], 0.0)
    again = generate_problem(panda, ws, family, 0, seed=3)
    assert again is not None and again.objects == problem.objects  # seeded
    np.testing.assert_array_equal(again.goal, problem.goal)


def test_a_path_through_a_scene_box_collides(panda: MeshChecker) -> None:
    start = np.array([-1.0, 0.3, 0.0, -1.8, 0.0, 2.0, 0.8])
    goal = np.array([1.0, 0.3, 0.0, -1.8, 0.0, 2.0, 0.8])
    middle = panda.tip_position((start + goal) / 2)
    box = {"id": "crate", "type": "box", "size": [0.1, 0.1, 0.1],
           "pose": {"position": middle.tolist(), "orientation": [0.0, 0.0, 0.0, 1.0]}}  # fmt: skip
    panda.set_scene([box])
    assert panda.is_free(start) and panda.is_free(goal)  # only the motion hits it
    verdict = panda.check_path(np.stack([start, goal]))
    assert verdict.collides and not verdict.self_collides
    assert 0 < verdict.scene_samples < verdict.samples
    assert verdict.max_depth > 0.01
    assert any(pair.endswith("–crate") for pair in verdict.scene_pairs)
    panda.set_scene([])
    assert not panda.check_path(np.stack([start, goal])).collides
