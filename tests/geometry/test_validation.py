"""Certified validation: thin obstacles between samples, near-contact motions, limits."""

from __future__ import annotations

import numpy as np
import pytest

from tests.robots import BRANCHED_URDF, ROD_URDF
from trajcache.geometry.errors import StateError
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene, SceneObject
from trajcache.geometry.validation.sampling import sample_counts
from trajcache.geometry.validation.validator import (
    Resolution,
    TrajectoryValidator,
    ValidationStatus,
    interpolate,
)
from trajcache.reference.robot import STOWED_ARM, reference_model

STEP = Resolution().joint_rad


@pytest.fixture(scope="module")
def swing():  # type: ignore[no-untyped-def]
    return load_robot_model(ROD_URDF)


def _plate(angle: float, radius: float, *, thickness: float = 0.002, length: float = 0.1) -> Scene:
    """A thin vertical plate lying along the radial direction at `angle`, centred at `radius`."""
    c, s = np.cos(angle), np.sin(angle)
    pose = np.eye(4)
    pose[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    pose[:3, 3] = [radius * c, radius * s, 0.5]
    plate = SceneObject("plate", Shape(ShapeKind.BOX, (length, thickness, 0.2)), pose)
    return Scene(objects=(plate,), env={}, hash=f"plate-{angle:.6f}-{radius:.4f}-{thickness}")


def _dense_collides(validator: TrajectoryValidator, key: np.ndarray, factor: int = 200) -> bool:
    fine = interpolate(
        key, validator.model, Resolution(0.04 / factor, 0.04 / factor, STEP / factor)
    )
    return bool(validator.checker.check(fine).first_collision >= 0)


def test_interpolation_respects_steps_and_keeps_key_states(swing) -> None:  # type: ignore[no-untyped-def]
    key = np.array([[0.0], [1.0], [0.5]])
    dense = interpolate(key, swing, Resolution())
    assert np.all(np.abs(np.diff(dense[:, 0])) <= STEP + 1e-12)
    for state in key:
        assert np.any(np.all(np.isclose(dense, state), axis=1))
    assert dense[0, 0] == 0.0 and dense[-1, 0] == 0.5


def test_thin_obstacle_between_samples_is_missed_by_plain_and_caught_by_certified(swing) -> None:  # type: ignore[no-untyped-def]
    key = np.array([[0.0], [1.0]])
    samples = interpolate(key, swing, Resolution())
    between = (samples[10, 0] + samples[11, 0]) / 2.0
    scene = _plate(between, 0.9)
    plain = TrajectoryValidator(swing, scene, certified=False).validate(key)
    certified = TrajectoryValidator(swing, scene, certified=True).validate(key)
    assert plain.status is ValidationStatus.VALID  # the per-sample check really misses it
    assert _dense_collides(TrajectoryValidator(swing, scene), key)  # ...and it really is there
    assert certified.status is ValidationStatus.COLLISION
    assert certified.contacts and certified.contacts[0].link == "rod"
    assert certified.contacts[0].other == "plate"


@pytest.mark.parametrize("clearance", [1e-3, 3e-4])
def test_near_contact_motion_is_certified_not_rejected(swing, clearance: float) -> None:  # type: ignore[no-untyped-def]
    # The plate's near end is `clearance` past the rod's tip, which moves 1.2 cm per sample
    # (certification samples a third of the resolution's 3.5 cm): padding each sample by its
    # motion would call every one of these motions a collision.
    key = np.array([[0.0], [1.0]])
    scene = _plate(0.5, 1.0 + clearance + 0.05)
    validator = TrajectoryValidator(swing, scene)
    step = float(
        np.max(np.abs(np.diff(interpolate(key, swing, Resolution(), validator.subdivision)[:, 0])))
    )
    assert clearance < step / 10  # the tip (1 m out) moves far more than the clearance
    result = validator.validate(key)
    assert result.status is ValidationStatus.VALID, result.message
    assert result.subdivisions > 0  # it had to advance between samples, and that proved it safe
    assert not _dense_collides(validator, key)


def test_closer_than_certifiable_is_too_close_and_names_the_pair(swing) -> None:  # type: ignore[no-untyped-def]
    key = np.array([[0.0], [1.0]])
    scene = _plate(0.5, 1.0 + 5e-5 + 0.05)  # 50 µm: below the 0.1 mm that can be certified
    validator = TrajectoryValidator(swing, scene)
    result = validator.validate(key)
    assert result.status is ValidationStatus.TOO_CLOSE
    assert not _dense_collides(validator, key)  # not a collision, just too close to prove
    assert [(c.link, c.other) for c in result.contacts] == [("rod", "plate")]
    assert "rod" in result.message and "plate" in result.message
    assert result.state is not None and 0.45 < result.state[0] < 0.55


def test_certified_never_accepts_a_colliding_segment(swing) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(7)
    accepted = rejected = 0
    for _ in range(60):
        a, b = rng.uniform(-1.5, 1.5, size=2)
        scene = _plate(
            rng.uniform(-1.5, 1.5), rng.uniform(0.2, 1.05), thickness=rng.uniform(0.001, 0.01)
        )
        key = np.array([[a], [b]])
        validator = TrajectoryValidator(swing, scene)
        result = validator.validate(key)
        if result.valid:
            accepted += 1
            assert not _dense_collides(validator, key), (a, b)
        else:
            rejected += 1
    assert accepted > 5 and rejected > 5  # the sample exercises both outcomes


def test_out_of_limits_is_reported_with_joint_name(swing) -> None:  # type: ignore[no-untyped-def]
    result = TrajectoryValidator(swing, _plate(2.0, 5.0)).validate(np.array([[0.0], [3.5]]))
    assert result.status is ValidationStatus.OUT_OF_LIMITS
    assert "j=" in result.message


def test_wrong_state_length_is_a_state_error(swing) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(StateError):
        TrajectoryValidator(swing, _plate(2.0, 5.0)).validate(np.array([[0.0, 1.0], [1.0, 0.0]]))


def test_start_in_collision_reports_first_sample(swing) -> None:  # type: ignore[no-untyped-def]
    scene = _plate(0.0, 0.5, thickness=0.05)
    result = TrajectoryValidator(swing, scene).validate(np.array([[0.0], [1.0]]))
    assert result.status is ValidationStatus.COLLISION
    assert result.state is not None and result.state[0] == pytest.approx(0.0)


def test_one_segment_is_sampled_as_the_start_of_a_longer_trajectory() -> None:
    model = reference_model()
    a = np.array([0.0, 0.0, 3.1, *STOWED_ARM])
    b = a.copy()
    b[0], b[2], b[4] = 1.0, -3.1, b[4] + 0.35  # θ takes the short way through ±π
    one = interpolate(np.stack([a, b]), model, Resolution())
    two = interpolate(np.stack([a, b, a]), model, Resolution())
    np.testing.assert_array_equal(one, two[: len(one)])
    np.testing.assert_array_equal(one[-1], b)
    assert np.all(np.abs(np.diff(one[:, 0])) <= 0.04 + 1e-12)


@pytest.mark.parametrize("subdivision", [1, 3])
def test_one_segment_of_a_fixed_base_is_sampled_as_within_a_longer_one(subdivision: int) -> None:
    model = load_robot_model(BRANCHED_URDF, base="fixed")
    rng = np.random.default_rng(8)
    for _ in range(20):
        a, b = rng.uniform(-1.0, 1.0, (2, model.dof))
        one = interpolate(np.stack([a, b]), model, Resolution(), subdivision)
        two = interpolate(np.stack([a, b, a]), model, Resolution(), subdivision)
        np.testing.assert_array_equal(one, two[: len(one)])
        np.testing.assert_array_equal(one[-1], b)
        assert len(one) - 1 == sample_counts(np.stack([a, b]), model, Resolution(), subdivision)[0]
