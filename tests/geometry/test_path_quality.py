"""Quality metrics: path lengths, the end-effector link, clearance to the scene."""

from __future__ import annotations

import dataclasses
import itertools

import fcl
import numpy as np
import pytest

from tests.robots import BRANCHED_URDF
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.space import path_length, segment_deltas
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.path_quality import (
    MAX_DISTANCE_QUERIES,
    Quality,
    ee_path_length,
    end_effector_link,
    min_clearance,
)
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.validation.validator import Resolution, interpolate
from trajcache.reference.restroom import restroom_scene
from trajcache.reference.robot import STOWED_ARM, reference_model


@pytest.fixture(scope="module")
def branched() -> RobotModel:
    return load_robot_model(BRANCHED_URDF, base="planar")


def test_path_length_takes_the_base_angle_the_short_way() -> None:
    states = np.array([[0.0, 0.0, 3.1, 0.0], [3.0, 4.0, -3.1, 0.0]])
    expected = np.linalg.norm([3.0, 4.0, 2 * np.pi - 6.2, 0.0])
    assert path_length(states, base=BaseType.PLANAR) == pytest.approx(expected)
    assert path_length(states, base=BaseType.FIXED) == pytest.approx(np.linalg.norm([3, 4, 6.2, 0]))
    assert path_length(states[:1], base=BaseType.PLANAR) == 0.0


def test_end_effector_is_the_tip_of_the_longest_chain_or_the_configured_link(
    branched: RobotModel,
) -> None:
    assert reference_model().link_names[end_effector_link(reference_model())] == "tool_tip"
    assert branched.link_names[end_effector_link(branched)] == "tip"
    camera = dataclasses.replace(branched, end_effector_link="camera")
    assert camera.link_names[end_effector_link(camera)] == "camera"
    with pytest.raises(ValueError, match="nowhere"):
        end_effector_link(dataclasses.replace(branched, end_effector_link="nowhere"))


def _chord_sum(model: RobotModel, states: np.ndarray, step: float, most: int) -> float:
    """`ee_path_length` by its docstring, in numpy: the compiled one is checked against it."""
    deltas = segment_deltas(states, base=model.base)
    steps = np.abs(deltas).max(axis=1) / step
    scale = min(1.0, most / steps.sum()) if steps.sum() > 0 else 1.0
    dense = [
        states[k] + j / count * deltas[k]
        for k, count in enumerate(np.maximum(np.ceil(steps * scale), 1).astype(int))
        for j in range(count)
    ]
    tips = link_transforms(model, np.array([*dense, states[-1]]))[:, end_effector_link(model)]
    return float(np.linalg.norm(np.diff(tips[:, :3, 3], axis=0), axis=1).sum())


@pytest.mark.parametrize("base", ["planar", "fixed"])
def test_end_effector_length_is_the_chord_sum_its_docstring_defines(base: str) -> None:
    model = load_robot_model(BRANCHED_URDF, base=base)
    rng = np.random.default_rng(4)
    for n, step, most in itertools.product((2, 3, 9), (0.05, 0.01), (16, 1000)):
        states = rng.uniform(
            np.maximum(model.lower, -4), np.minimum(model.upper, 4), (n, model.dof)
        )
        states[1, -1] = states[0, -1]  # a segment that moves one value only
        expected = _chord_sum(model, states, step, most)
        assert ee_path_length(model, states, step=step, max_samples=most) == pytest.approx(
            expected, rel=1e-12, abs=1e-12
        )
    assert ee_path_length(model, states[:1]) == 0.0


def test_end_effector_length_of_a_rotation_is_the_arc(branched: RobotModel) -> None:
    # turning the arm by 2 rad about its axis moves the tip on a circle; radius from FK
    states = np.array([[0.0, 0.0, 0.0, 0.2, -1.0], [0.0, 0.0, 0.0, 0.2, 1.0]])
    tip = end_effector_link(branched)
    frames = link_transforms(branched, states)
    axis = frames[0, branched.link_names.index("arm"), :3, 2]
    offset = frames[0, tip, :3, 3] - frames[0, branched.link_names.index("arm"), :3, 3]
    radius = np.linalg.norm(offset - (offset @ axis) * axis)
    arc = radius * 2.0
    length = ee_path_length(branched, states)
    assert arc * 0.995 <= length <= arc
    fine = ee_path_length(branched, states, step=0.005, max_samples=1000)
    assert fine == pytest.approx(arc, rel=1e-5)
    base_drive = np.array([[0.0, 0.0, 0.0, 0.2, 0.0], [3.0, 4.0, 0.0, 0.2, 0.0]])
    assert ee_path_length(branched, base_drive) == pytest.approx(5.0)


def _brute_force_clearance(checker: CollisionChecker, states: np.ndarray) -> float:
    samples = interpolate(states, checker.model, Resolution())
    poses = checker.element_poses(samples)
    objects = checker.robot.objects()
    best = np.inf
    for n, e in itertools.product(range(len(samples)), range(len(objects))):
        objects[e].setTranslation(poses[n, e, :3, 3])
        objects[e].setRotation(poses[n, e, :3, :3])
        for obstacle in checker.scene.objects:
            d = fcl.distance(objects[e], obstacle, fcl.DistanceRequest(), fcl.DistanceResult())
            best = min(best, max(d, 0.0))
    return float(best)


def test_clearance_equals_the_brute_force_minimum() -> None:
    model = reference_model()
    scene = restroom_scene(doors=[30.0, 60.0, 90.0])
    checker = CollisionChecker(model, scene)
    stowed = [0.95, 1.2, np.pi / 2, *STOWED_ARM]
    reach = [0.95, 1.2, np.pi / 2, 0.3, 0.2, 0.0, 1.0, 0.0, 0.9, 0.0]
    states = np.array([stowed, reach])
    found = min_clearance(checker, states)
    assert found is not None and found.exact
    assert found.distance == pytest.approx(_brute_force_clearance(checker, states), abs=1e-9)
    assert found.link in model.link_names and found.object in {o.id for o in scene.objects}
    assert MAX_DISTANCE_QUERIES > 1000


def _box(oid: str, position: list[float], size: list[float]) -> dict[str, object]:
    return {"id": oid, "type": "box", "size": size, "pose": {"position": position}}


def test_clearance_without_obstacles_and_in_contact(branched: RobotModel) -> None:
    states = np.array([[0.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0]])
    empty = parse_scene({"objects": []})
    assert min_clearance(CollisionChecker(branched, empty), states) is None
    far = parse_scene({"objects": [_box("far", [5.0, 0.0, 0.0], [0.1, 0.1, 0.1])]})
    found = min_clearance(CollisionChecker(branched, far), states)
    assert found is not None and 4.0 < found.distance < 5.0
    touching = parse_scene({"objects": [_box("post", [0.0, 0.0, 0.3], [0.1, 0.1, 2.0])]})
    found = min_clearance(CollisionChecker(branched, touching), states)
    assert found is not None and found.distance == 0.0 and found.object == "post"


def test_quality_as_dict() -> None:
    q = Quality(path_length=1.0, ee_path_length=0.5, min_clearance=None, duration_s=2.0)
    assert q.as_dict() == {
        "path_length": 1.0,
        "ee_path_length": 0.5,
        "min_clearance": None,
        "duration_s": 2.0,
    }
