"""Where a rejected path failed: its first failing sample, and the pairs or joints at fault."""

from __future__ import annotations

import numpy as np
import pytest

from tests.robots import ROD_URDF
from trajcache.cache.memo import MemoScope, ValidationMemo, validate_with_memo
from trajcache.geometry.collision.checker import ContactKind
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene, SceneObject
from trajcache.geometry.validation.failure import locate_failure
from trajcache.geometry.validation.validator import (
    Resolution,
    TrajectoryValidator,
    ValidationStatus,
    interpolate,
)
from trajcache.reference.robot import STOWED_ARM, reference_model


@pytest.fixture(scope="module")
def swing() -> RobotModel:
    return load_robot_model(ROD_URDF)


def _post(angle: float, radius: float, width: float) -> Scene:
    """A vertical post of `width` across the rod's sweep at `angle`, `radius` out."""
    pose = np.eye(4)
    pose[:3, 3] = [radius * np.cos(angle), radius * np.sin(angle), 0.5]
    post = SceneObject("post", Shape(ShapeKind.BOX, (width, width, 0.3)), pose)
    return Scene(objects=(post,), env={}, hash=f"post-{angle}-{radius}-{width}")


def test_a_collision_is_placed_on_its_first_colliding_sample(swing: RobotModel) -> None:
    key = np.array([[0.0], [1.0]])
    samples = interpolate(key, swing, Resolution())
    validator = TrajectoryValidator(swing, _post(float(samples[17, 0]), 0.6, 0.05))
    result = validator.validate(key)
    assert result.status is ValidationStatus.COLLISION
    failure = locate_failure(validator, key, result)
    assert failure is not None and failure.samples == len(samples) and failure.segment == 0
    # the first sample that reaches the post: before the post's centre, and it does collide
    assert 12 <= failure.sample < 17
    first = validator.checker.check(samples).first_collision
    assert failure.position <= first
    assert [(c.link, c.other, c.kind) for c in failure.contacts] == [
        ("rod", "post", ContactKind.SCENE)
    ]
    step = samples[failure.sample + 1] - samples[failure.sample]
    expected = samples[failure.sample] + failure.at * step
    np.testing.assert_allclose(failure.state, expected, atol=1e-9)


def test_a_thin_obstacle_between_samples_fails_between_them(swing: RobotModel) -> None:
    key = np.array([[0.0], [1.0]])
    samples = interpolate(key, swing, Resolution())
    between = float(samples[10, 0] + samples[11, 0]) / 2.0
    validator = TrajectoryValidator(swing, _post(between, 0.9, 0.002))
    result = validator.validate(key)
    failure = locate_failure(validator, key, result)
    assert failure is not None and failure.status is ValidationStatus.COLLISION
    assert failure.sample == 10 and 0.0 < failure.at < 1.0
    assert failure.contacts and failure.contacts[0].other == "post"


def test_a_path_validated_by_its_ends_is_placed_on_the_whole_path(swing: RobotModel) -> None:
    key = np.array([[0.0], [0.3], [0.6], [0.9]])
    samples = interpolate(key, swing, Resolution())
    validator = TrajectoryValidator(swing, _post(float(samples[-4, 0]), 0.6, 0.05))
    scope = MemoScope.of(validator)
    assert scope is not None
    memo = ValidationMemo()
    memo.remember(scope, key[1:-1])  # the interior is known: only the end segments are checked
    result, use = validate_with_memo(key, validate_fn=validator.validate, memo=memo, scope=scope)
    assert use.value == "ends" and result.status is ValidationStatus.COLLISION
    failure = locate_failure(validator, key, result)
    assert failure is not None and failure.segment == 2
    assert len(samples) - 9 <= failure.sample < len(samples) - 4  # counted from the path's start


def test_limits_name_the_joints(swing: RobotModel) -> None:
    key = np.array([[0.0], [3.5]])
    validator = TrajectoryValidator(swing, _post(2.0, 5.0, 0.05))
    result = validator.validate(key)
    failure = locate_failure(validator, key, result)
    assert failure is not None and failure.status is ValidationStatus.OUT_OF_LIMITS
    assert failure.joints == ["j"] and failure.contacts == []
    samples = interpolate(key, swing, Resolution())
    assert failure.at == 0.0 and samples[failure.sample, 0] > swing.upper[0]
    assert samples[failure.sample - 1, 0] <= swing.upper[0]


def test_a_valid_path_has_no_failure(swing: RobotModel) -> None:
    key = np.array([[0.0], [1.0]])
    validator = TrajectoryValidator(swing, _post(2.5, 0.6, 0.05))
    assert locate_failure(validator, key, validator.validate(key)) is None


def test_a_base_turning_through_pi_is_placed_on_the_short_way() -> None:
    model = reference_model()
    a = np.array([0.0, 0.0, 3.0, *STOWED_ARM])
    b = a.copy()
    b[0], b[2] = 1.0, -3.0  # θ takes the short way through ±π
    key = np.stack([a, b])
    samples = interpolate(key, model, Resolution())
    wall = SceneObject("wall", Shape(ShapeKind.BOX, (0.05, 4.0, 2.0)), np.eye(4))
    wall.pose[:3, 3] = [float(samples[20, 0]) + 0.45, 0.0, 1.0]
    validator = TrajectoryValidator(model, Scene(objects=(wall,), env={}, hash="wall"))
    result = validator.validate(key)
    failure = locate_failure(validator, key, result)
    assert failure is not None and failure.status is ValidationStatus.COLLISION
    assert failure.contacts[0].other == "wall" and 0 < failure.sample < len(samples) - 1
    step = samples[failure.sample + 1] - samples[failure.sample]
    assert abs(step[2]) < 0.05  # consecutive samples: the short way, not across the circle
    expected = samples[failure.sample] + failure.at * step
    np.testing.assert_allclose(failure.state, expected, atol=1e-9)
    assert validator.checker.check(samples[: failure.sample]).first_collision == -1
