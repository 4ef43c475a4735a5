"""Swept envelopes (`validation/envelope.py`): every point of the robot along a path, between
samples too, lies in some ball; an object found clear of them is clear of the robot at 20×
denser samples; an object on the robot's way never is. The Panda as shipped (meshes) and the
reference robot (a planar base, primitives)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.model.kinematics import forward_kinematics
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import SceneObject, make_scene
from trajcache.geometry.validation.envelope import Envelope, swept_envelope
from trajcache.geometry.validation.validator import Resolution, TrajectoryValidator, interpolate
from trajcache.reference.example_robots import ROBOTS
from trajcache.reference.robot import reference_model

COARSE = Resolution(0.3, 0.3, 0.3)  # far apart: the motion between samples must be covered


def _panda() -> RobotModel:
    robot = ROBOTS["panda"]
    return load_robot_model(robot.urdf, files=robot.files(), srdf=robot.srdf, group="arm")


@pytest.fixture(scope="module", params=["panda", "reference"])
def model(request: pytest.FixtureRequest) -> RobotModel:
    return _panda() if request.param == "panda" else reference_model()


def _path(model: RobotModel, rng: np.random.Generator) -> FloatArray:
    """Four states, each a large random step from the last, within the limits (a planar base
    drives a metre or so)."""
    lower = np.where(np.isfinite(model.lower), model.lower, -1.0)
    upper = np.where(np.isfinite(model.upper), model.upper, 1.0)
    states = [rng.uniform(lower, upper)]
    for _ in range(3):
        states.append(np.clip(states[-1] + rng.normal(0.0, 0.8, model.dof), lower, upper))
    return np.array(states)


def _surface(shape: Shape, rng: np.random.Generator) -> FloatArray:
    """Points of the shape's surface in its frame (a mesh's vertices)."""
    if shape.kind is ShapeKind.MESH:
        assert shape.vertices is not None
        return np.asarray(shape.vertices, dtype=float)
    directions = rng.normal(size=(24, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    if shape.kind is ShapeKind.BOX:
        return directions / np.abs(directions).max(axis=1, keepdims=True) * shape.half_extents()
    if shape.kind is ShapeKind.SPHERE:
        return directions * shape.size[0]
    radius, length = shape.size
    rim = directions[:, :2] / np.linalg.norm(directions[:, :2], axis=1, keepdims=True) * radius
    ends = np.where(directions[:, 2:] > 0, length / 2.0, -length / 2.0)
    points = np.column_stack([rim, ends])
    if shape.kind is ShapeKind.CAPSULE:
        points[:, 2] += np.sign(points[:, 2]) * radius
    return points


def _robot_points(model: RobotModel, states: FloatArray, rng: np.random.Generator) -> FloatArray:
    """World points (M, 3) of every element's surface at each of `states`."""
    links = forward_kinematics(model, states)
    out = []
    for element in model.elements:
        local = _surface(element.shape, rng)
        frames = links[:, element.link] @ element.origin  # (N, 4, 4)
        out.append((frames[:, None, :3, :3] @ local[None, :, :, None])[..., 0]
                   + frames[:, None, :3, 3])  # fmt: skip
    return np.concatenate([p.reshape(-1, 3) for p in out])


def _inside(envelope: Envelope, points: FloatArray) -> np.ndarray:
    gaps = np.linalg.norm(points[:, None, :] - envelope.centres[None], axis=2)
    return np.asarray((gaps <= envelope.radii[None]).any(axis=1))


def test_every_point_of_the_robot_along_the_path_lies_in_the_envelope(model: RobotModel) -> None:
    """Samples 0.3 apart, checked at 40 times as many: the motion between samples, not only
    the samples, must be inside."""
    rng = np.random.default_rng(5)
    validator = TrajectoryValidator(model, make_scene([]), resolution=COARSE)
    for _ in range(6):
        key = _path(model, rng)
        envelope = swept_envelope(validator, key)
        dense = interpolate(key, model, Resolution(0.3 / 40, 0.3 / 40, 0.3 / 40))
        points = _robot_points(model, dense, rng)
        assert _inside(envelope, points).all()


def _thing(rng: np.random.Generator, centre: FloatArray, k: int) -> SceneObject:
    """A box, sphere, cylinder or mesh of a few centimetres about `centre`, turned at random."""
    angle = rng.uniform(-math.pi, math.pi)
    pose = np.eye(4)
    pose[:3, :3] = [[1, 0, 0], [0, math.cos(angle), -math.sin(angle)],
                    [0, math.sin(angle), math.cos(angle)]]  # fmt: skip
    pose[:3, 3] = centre
    size = rng.uniform(0.01, 0.08)
    shapes = [
        Shape(ShapeKind.BOX, (size, 2 * size, 0.005)),
        Shape(ShapeKind.SPHERE, (size,)),
        Shape(ShapeKind.CYLINDER, (size, 3 * size)),
        Shape(ShapeKind.MESH, (),
              vertices=rng.uniform(-size, size, (8, 3)) + np.array([size, 0, 0]),
              faces=np.array([[0, 1, 2], [2, 3, 4], [4, 5, 6], [6, 7, 0]])),
    ]  # fmt: skip
    return SceneObject(f"thing_{k}", shapes[k % len(shapes)], pose)


def test_an_object_clear_of_the_envelope_is_clear_of_the_robot(model: RobotModel) -> None:
    """Objects put near the robot's points along random paths: each one found clear is free at
    every state of a 20× denser sampling; one put on a point of the robot's way is never clear."""
    rng = np.random.default_rng(11)
    validator = TrajectoryValidator(model, make_scene([]))
    clear = blocked = 0
    for _ in range(4):
        key = _path(model, rng)
        envelope = swept_envelope(validator, key)
        dense = interpolate(key, model, Resolution(0.04 / 20, 0.04 / 20, 0.035 / 20))
        points = _robot_points(model, dense[:: max(len(dense) // 40, 1)], rng)
        for k in range(24):
            point = points[rng.integers(len(points))]
            thing = _thing(rng, point + rng.normal(0.0, 0.25, 3), k)
            if envelope.clear_of(thing):
                clear += 1
                checker = CollisionChecker(model, make_scene([thing]), self_collision=False)
                assert checker.check(dense).first_collision < 0
            at = np.eye(4)
            at[:3, 3] = point
            on_way = SceneObject("on_way", Shape(ShapeKind.SPHERE, (0.001,)), at)
            blocked += not envelope.clear_of(on_way)
    assert clear > 10 and blocked == 4 * 24, (clear, blocked)


def test_it_is_stored_to_the_bit() -> None:
    rng = np.random.default_rng(2)
    envelope = Envelope(rng.normal(size=(5, 3)), rng.uniform(0.0, 1.0, 5))
    again = Envelope.from_bytes(envelope.to_bytes())
    assert np.array_equal(again.centres, envelope.centres)
    assert np.array_equal(again.radii, envelope.radii)
    assert Envelope(np.zeros((0, 3)), np.zeros(0)).clear_of(
        SceneObject("x", Shape(ShapeKind.SPHERE, (1.0,)), np.eye(4))
    )
