"""Certified validation beyond one arm and one plate: self-collisions, the base, chunks, a
property test on the reference robot, and stopping at the first collision."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.robots import (
    BARE_JOINT_URDF,
    SLIDING_BALL_URDF,
    Z_AXIS,
    box,
    collision,
    joint,
    link,
    planar_arm,
)
from trajcache.geometry.collision.checker import COLLIDING, ContactKind
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.geometry.validation import validator as validator_module
from trajcache.geometry.validation.validator import (
    Resolution,
    TrajectoryValidator,
    ValidationStatus,
    interpolate,
)
from trajcache.reference.restroom import restroom_layout, restroom_scene
from trajcache.reference.robot import BASE_SIZE, STOWED_ARM, reference_model

STEP = Resolution().joint_rad


def _dense_collides(validator: TrajectoryValidator, key: FloatArray, factor: int = 50) -> bool:
    res = Resolution(0.04 / factor, 0.04 / factor, STEP / factor)
    fine = interpolate(key, validator.model, res)
    return bool(validator.checker.check(fine).first_collision >= 0)


def _rod_and_plate(angle: float) -> RobotModel:
    """A 1 m rod turning about z, and a thin plate on another link of the same robot (on a
    carriage, so that the two are not adjacent and their pair is checked)."""
    c, s = math.cos(angle), math.sin(angle)
    plate = (
        link("carriage"),
        link("plate", collision(box(0.1, 0.002, 0.2))),
        joint("shift", "prismatic", "root", "carriage", axis=Z_AXIS, limit=(0, 0.01)),
        joint(
            "mount", "fixed", "carriage", "plate", xyz=(0.9 * c, 0.9 * s, 0.5), rpy=(0, 0, angle)
        ),
    )
    urdf = planar_arm(
        (1.0,), name="rod_and_plate", links=("rod",), joints=("turn",), height=0.5, extra=plate
    )
    return load_robot_model(urdf)


def test_a_self_collision_between_samples_is_caught() -> None:
    key = np.array([[0.0, 0.0], [1.0, 0.0]])
    samples = interpolate(key, _rod_and_plate(0.0), Resolution())
    model = _rod_and_plate(float(samples[10, 0] + samples[11, 0]) / 2.0)
    empty = make_scene([])
    plain = TrajectoryValidator(model, empty, certified=False).validate(key)
    certified = TrajectoryValidator(model, empty).validate(key)
    assert plain.status is ValidationStatus.VALID  # the samples straddle the plate
    assert _dense_collides(TrajectoryValidator(model, empty), key)
    assert certified.status is ValidationStatus.COLLISION
    assert [(c.link, c.other, c.kind) for c in certified.contacts] == [
        ("rod", "plate", ContactKind.SELF)
    ]
    assert certified.state is not None and samples[10, 0] < certified.state[0] < samples[11, 0]


def _post(x: float, y: float) -> Scene:
    pose = np.eye(4)
    pose[:3, 3] = [x, y, 0.5]
    return make_scene([SceneObject("post", Shape(ShapeKind.CYLINDER, (0.001, 1.0)), pose)])


def test_a_turning_base_sweeps_a_thin_post_between_samples() -> None:
    model = reference_model()
    start = np.array([0.0, 0.0, 0.0, *STOWED_ARM])
    goal = start.copy()
    goal[2] = 1.0
    key = np.stack([start, goal])
    heading = interpolate(key, model, Resolution())[:, 2]
    corner = math.atan2(BASE_SIZE[1] / 2, BASE_SIZE[0] / 2)
    between = float(heading[10] + heading[11]) / 2.0 + corner
    radius = 0.99 * math.hypot(BASE_SIZE[0] / 2, BASE_SIZE[1] / 2)  # just inside the corner
    scene = _post(radius * math.cos(between), radius * math.sin(between))
    plain = TrajectoryValidator(model, scene, certified=False).validate(key)
    certified = TrajectoryValidator(model, scene).validate(key)
    assert plain.status is ValidationStatus.VALID
    assert _dense_collides(TrajectoryValidator(model, scene), key)
    assert certified.status is ValidationStatus.COLLISION
    assert ("base_link", "post") in {(c.link, c.other) for c in certified.contacts}


def test_a_collision_where_two_chunks_meet_is_caught(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(validator_module, "_CHUNK", 8)  # chunks share their end sample
    key = np.array([[0.0, 0.0], [1.0, 0.0]])
    samples = interpolate(key, _rod_and_plate(0.0), Resolution())
    for pair in (7, 8):  # the segment ending a chunk, the one starting the next
        model = _rod_and_plate(float(samples[pair, 0] + samples[pair + 1, 0]) / 2.0)
        result = TrajectoryValidator(model, make_scene([])).validate(key)
        assert result.status is ValidationStatus.COLLISION, pair
        assert result.state is not None
        assert samples[pair, 0] < result.state[0] < samples[pair + 1, 0]


def _plates(*angles: float) -> Scene:
    objects = []
    for k, angle in enumerate(angles):
        pose = np.eye(4)
        c, s = math.cos(angle), math.sin(angle)
        pose[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
        pose[:3, 3] = [0.9 * c, 0.9 * s, 0.5]
        objects.append(SceneObject(f"plate{k}", Shape(ShapeKind.BOX, (0.1, 0.05, 0.2)), pose))
    return make_scene(objects)


def test_the_first_collision_stops_validation() -> None:
    model = _rod_and_plate(-2.0)  # its own plate is out of the way
    key = np.array([[0.0, 0.0], [1.0, 0.0]])
    result = TrajectoryValidator(model, _plates(0.8, 0.3)).validate(key)
    assert result.status is ValidationStatus.COLLISION
    assert [c.other for c in result.contacts] == ["plate1"]  # at 0.3 rad, before 0.8
    assert result.state is not None and result.state[0] < 0.3
    samples = interpolate(key, model, Resolution())
    assert result.narrow_checks < len(samples)


def _near_motions(
    model: RobotModel, scene: Scene, rng: np.random.Generator, count: int
) -> list[FloatArray]:
    """Short arm motions at the stations, from free states, many of them grazing something."""
    validator = TrajectoryValidator(model, scene, certified=False)
    stations = np.array([s.pose for s in restroom_layout().stations])
    off = model.arm_offset
    lower, upper = np.maximum(model.lower[off:], -np.pi), np.minimum(model.upper[off:], np.pi)
    motions: list[FloatArray] = []
    while len(motions) < count:
        start = np.concatenate([stations[rng.integers(len(stations))], rng.uniform(lower, upper)])
        if validator.checker.check(start[None]).status[0] == COLLIDING:
            continue
        goal = start.copy()
        goal[off:] = np.clip(goal[off:] + rng.normal(0.0, 0.4, size=len(lower)), lower, upper)
        motions.append(np.stack([start, goal]))
    return motions


def test_certified_never_accepts_what_a_denser_check_rejects() -> None:
    model = reference_model()
    scene = restroom_scene(doors=(10, 50, 90), seats=(90, 0, 0))
    certified = TrajectoryValidator(model, scene)
    plain = TrajectoryValidator(model, scene, certified=False)
    outcomes = {"valid": 0, "rejected": 0, "between": 0}
    for key in _near_motions(model, scene, np.random.default_rng(8), 60):
        verdict = certified.validate(key)
        dense = _dense_collides(certified, key, factor=20)
        if verdict.valid:
            outcomes["valid"] += 1
            assert not dense
        else:
            outcomes["rejected"] += 1
            outcomes["between"] += plain.validate(key).valid and dense
        if not plain.validate(key).valid:
            assert not verdict.valid  # never laxer than the paper's per-sample check
    assert outcomes["valid"] > 10 and outcomes["rejected"] > 10, outcomes


def _mesh_plate(angle: float, radius: float, thickness: float) -> Scene:
    """The plate of `test_validation` as a triangle mesh (its box's 8 corners, 12 triangles)."""
    size = np.array([0.1, thickness, 0.2]) / 2.0
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * size
    faces = np.array(
        [
            [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
            [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],
        ]
    )  # fmt: skip
    c, s = math.cos(angle), math.sin(angle)
    pose = np.eye(4)
    pose[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    pose[:3, 3] = [radius * c, radius * s, 0.5]
    mesh = Shape(ShapeKind.MESH, vertices=corners, faces=faces)
    return make_scene([SceneObject("mesh_plate", mesh, pose)])


def test_mesh_obstacles_are_certified_like_primitives() -> None:
    model = _rod_and_plate(-2.0)
    key = np.array([[0.0, 0.0], [1.0, 0.0]])
    samples = interpolate(key, model, Resolution())
    thin = _mesh_plate(float(samples[10, 0] + samples[11, 0]) / 2.0, 0.9, 0.002)
    assert TrajectoryValidator(model, thin, certified=False).validate(key).valid
    caught = TrajectoryValidator(model, thin).validate(key)
    assert caught.status is ValidationStatus.COLLISION
    assert [c.other for c in caught.contacts] == ["mesh_plate"]
    near = _mesh_plate(0.5, 1.0 + 0.003 + 0.05, 0.002)  # 3 mm past the rod's tip
    passed = TrajectoryValidator(model, near).validate(key)
    assert passed.status is ValidationStatus.VALID, passed.message
    assert not _dense_collides(TrajectoryValidator(model, near), key)


def test_degenerate_inputs_validate() -> None:
    ghost = load_robot_model(BARE_JOINT_URDF)
    key = np.array([[0.0], [1.0]])
    assert TrajectoryValidator(ghost, restroom_scene()).validate(key).valid  # no geometry
    model = _rod_and_plate(-2.0)
    lone = np.array([[0.3, 0.0]])  # a single state: nothing between samples to certify
    assert TrajectoryValidator(model, _plates(0.8)).validate(lone).valid
    hit = TrajectoryValidator(model, _plates(0.3)).validate(lone)
    assert hit.status is ValidationStatus.COLLISION and hit.samples == 1


def _bracket(angle: float, height: float = 0.5) -> Scene:
    """A concave mesh: two plates 7 cm above and below the rod's sweep, joined by a wall past
    its tip. Its convex hull holds the rod; the mesh itself does not touch it."""
    import trimesh

    parts = [
        trimesh.creation.box((0.6, 0.2, 0.02), _translation(0.8, 0.0, -0.09)),
        trimesh.creation.box((0.6, 0.2, 0.02), _translation(0.8, 0.0, 0.09)),
        trimesh.creation.box((0.02, 0.2, 0.2), _translation(1.1, 0.0, 0.0)),
    ]
    mesh = trimesh.util.concatenate(parts)
    c, s = math.cos(angle), math.sin(angle)
    pose = np.eye(4)
    pose[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    pose[2, 3] = height
    shape = Shape(ShapeKind.MESH, vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces))
    return make_scene([SceneObject("bracket", shape, pose)])


def _translation(x: float, y: float, z: float) -> FloatArray:
    out = np.eye(4)
    out[:3, 3] = [x, y, z]
    return out


def test_a_path_inside_a_concave_mesh_s_hull_is_certified() -> None:
    model, scene = _rod_and_plate(-2.0), _bracket(0.5)
    key = np.array([[0.0, 0.0], [1.0, 0.0]])
    validator = TrajectoryValidator(model, scene)
    samples = interpolate(key, model, Resolution())
    checker = validator.checker
    posed = checker.pose(samples)
    rows = np.array([[k, 0, 0] for k in range(len(samples))])
    inside = checker.clearance.scene_slabs(posed, rows) <= 0.0
    assert inside.sum() >= 5  # the hull-based levels cannot settle these samples
    exact = checker.narrow.scene_exact(posed, rows)
    assert exact.min() == pytest.approx(0.08 - 0.01, abs=1e-4)  # the gap less the rod's radius
    found = validator.validate(key)
    assert found.status is ValidationStatus.VALID, found.message
    assert not _dense_collides(validator, key)
    raised = TrajectoryValidator(model, _bracket(0.5, height=0.585)).validate(key)
    assert raised.status is ValidationStatus.COLLISION  # the bottom plate now meets the rod


def test_exact_distances_stay_below_the_mesh_s_true_distance() -> None:
    import trimesh

    scene = _bracket(0.3)
    shape = scene.objects[0].shape
    assert shape.vertices is not None
    mesh = trimesh.Trimesh(shape.vertices, shape.faces, process=False)
    model = load_robot_model(SLIDING_BALL_URDF)
    checker = TrajectoryValidator(model, scene).checker
    rng = np.random.default_rng(11)
    truths, bounds = [], []
    for _ in range(60):
        centre = np.array([rng.uniform(0.3, 1.3), rng.uniform(-0.3, 0.3), rng.uniform(0.3, 0.7)])
        local = np.linalg.solve(scene.objects[0].pose, np.r_[centre, 1.0])[:3]
        _, distance, _ = trimesh.proximity.closest_point(mesh, local[None])
        if distance[0] <= 0.02:
            continue
        # The ball rides on x; the rest of its place comes from a shifted root (the pose).
        posed = checker.pose(np.array([[0.0]]))
        posed.links[0, :, :3, 3] = centre
        bounds.append(float(checker.narrow.scene_exact(posed, np.array([[0, 0, 0]]))[0]))
        truths.append(float(distance[0]) - 0.02)
    assert len(truths) >= 30
    assert np.all(np.array(bounds) <= np.array(truths) + 1e-12)
    assert np.all(np.array(bounds) >= np.array(truths) - 2e-5)
