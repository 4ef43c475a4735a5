"""The independent dense check: known colliding and free paths, and agreement with the service."""

from __future__ import annotations

import numpy as np
import pytest

from harness.dense import DenseChecker, reference_checker
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import make_scene
from trajcache.geometry.validation.validator import TrajectoryValidator
from trajcache.reference import restroom_scene
from trajcache.reference.cleaning import cleaning_run
from trajcache.reference.robot import STOWED_ARM, reference_model
from trajcache.reference.tasks import work_stations


@pytest.fixture(scope="module")
def checker() -> DenseChecker:
    return reference_checker()


def test_interpolation_is_four_times_finer_than_the_paper(checker: DenseChecker) -> None:
    start = np.array([0.0, 0.0, 3.1, *STOWED_ARM])
    goal = start.copy()
    goal[0] += 1.0  # 1 m of base translation: 100 steps of 0.01 m
    goal[2] = -3.1  # the short way round: 0.083 rad, fewer steps than the translation
    goal[4] += 0.35  # 0.35 rad of joint 2: 40 steps of 0.00875 rad
    dense = checker.interpolate(np.stack([start, goal]))
    assert len(dense) == 101
    np.testing.assert_allclose(dense[0], start)
    steps = np.abs(np.diff(dense, axis=0))
    assert steps[:, 0].max() <= 0.01 + 1e-12
    assert steps[:, 4].max() <= 0.00875 + 1e-12
    assert steps[:, 2].max() < 0.01  # no long turn through ±π
    assert dense[-1][2] == pytest.approx(start[2] + 2 * np.pi - 6.2)


def test_a_drive_through_the_north_wall_collides_between_free_key_states(
    checker: DenseChecker,
) -> None:
    scene = restroom_scene(doors=(0, 0, 0), seats=(0, 0, 0))
    start = np.array([3.3, 1.5, 0.0, *STOWED_ARM])
    goal = np.array([3.3, 4.5, 0.0, *STOWED_ARM])  # beyond the wall, outside the room
    service = CollisionChecker(reference_model(), scene)
    assert not service.state_contacts(start) and not service.state_contacts(goal)
    verdict = checker.check(np.stack([start, goal]), scene.hash, scene_to_payload(scene))
    assert verdict.collides
    assert ("base_link", "wall_north") in verdict.contacts
    assert verdict.samples == 301


def test_a_self_collision_is_found(checker: DenseChecker) -> None:
    scene = make_scene([], {})
    state = np.array([0.0, 0.0, 0.0, 0.0, -1.3, 0.0, 1.0, 0.0, 3.14, 0.0])
    verdict = checker.check(state[None], scene.hash, scene_to_payload(scene))
    assert verdict.collides
    assert ("link5", "link7") in verdict.contacts


def test_a_workload_motion_is_free_for_both_checkers(checker: DenseChecker) -> None:
    run = cleaning_run(1)
    call = run.calls[8]  # stall 1: spray bowl left → right, door open, seat up
    scene = run.scene_for(call)
    path = np.stack([call.start, call.goal])
    assert TrajectoryValidator(reference_model(), scene).validate(path).valid
    verdict = checker.check(path, scene.hash, scene_to_payload(scene))
    assert not verdict.collides and verdict.limit_samples == 0
    assert verdict.samples > 50


def test_per_state_verdicts_agree_with_the_service(checker: DenseChecker) -> None:
    model = reference_model()
    scene = restroom_scene(doors=(60, 20, 90), seats=(90, 0, 0))
    payload = scene_to_payload(scene)
    service = CollisionChecker(model, scene)
    rng = np.random.default_rng(7)
    stations = work_stations()
    lower, upper = np.maximum(model.lower[3:], -np.pi), np.minimum(model.upper[3:], np.pi)
    verdicts = []
    for i in range(300):
        base = np.array(stations[i % len(stations)].pose) + rng.normal(0, [0.3, 0.3, 0.5])
        state = np.concatenate([base, rng.uniform(lower, upper)])
        ours = checker.check(state[None], scene.hash, payload).collides
        theirs = bool(service.state_contacts(state))
        verdicts.append((ours, theirs))
    assert all(ours == theirs for ours, theirs in verdicts)
    assert 50 < sum(theirs for _, theirs in verdicts) < 250  # both kinds of state were tried
