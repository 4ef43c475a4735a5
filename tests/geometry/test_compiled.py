"""The compiled geometry core on a robot as shipped (the Panda of example-robot-data, with its
meshes and SRDF): forward kinematics against Pinocchio, every bound level against coal's exact
distances, and certified validation against a 20× denser check."""

from __future__ import annotations

import math

import coal
import numpy as np
import pinocchio as pin
import pytest

from trajcache.geometry.collision.checker import COLLIDING, CollisionChecker
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.geometry.validation.certify import CertifierOptions
from trajcache.geometry.validation.validator import (
    Resolution,
    TrajectoryValidator,
    ValidationStatus,
    interpolate,
)
from trajcache.reference.example_robots import ROBOTS


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    robot = ROBOTS["panda"]
    return load_robot_model(robot.urdf, files=robot.files(), srdf=robot.srdf, group="arm")


def _states(model: RobotModel, rng: np.random.Generator, count: int) -> FloatArray:
    return rng.uniform(model.lower, model.upper, size=(count, model.dof))


def test_forward_kinematics_matches_pinocchio(panda: RobotModel) -> None:
    pin_model = pin.buildModelFromXML(ROBOTS["panda"].urdf)
    data = pin_model.createData()
    for state in _states(panda, np.random.default_rng(1), 20):
        q = pin.neutral(pin_model)
        for joint_id in range(1, pin_model.njoints):
            name = pin_model.names[joint_id]
            value = (
                state[panda.state_names.index(name)]
                if name in panda.state_names
                else panda.held_values.get(name, 0.0)
            )
            q[pin_model.joints[joint_id].idx_q] = value
        pin.forwardKinematics(pin_model, data, q)
        pin.updateFramePlacements(pin_model, data)
        ours = link_transforms(panda, state)[0]
        for k, link in enumerate(panda.link_names):
            theirs = data.oMf[pin_model.getFrameId(link)].homogeneous
            np.testing.assert_allclose(ours[k], theirs, atol=1e-9, err_msg=link)


def _coal(shape: Shape) -> coal.CollisionGeometry:
    if shape.kind is ShapeKind.BOX:
        return coal.Box(*shape.size)
    if shape.kind is ShapeKind.SPHERE:
        return coal.Sphere(shape.size[0])
    if shape.kind is ShapeKind.CYLINDER:
        return coal.Cylinder(*shape.size)
    assert shape.vertices is not None and shape.faces is not None
    mesh = coal.BVHModelOBBRSS()
    mesh.beginModel(len(shape.faces), len(shape.vertices))
    mesh.addVertices(np.asarray(shape.vertices, dtype=float))
    mesh.addTriangles(np.asarray(shape.faces, dtype=np.int64))
    mesh.endModel()
    return mesh


def _distance(a: coal.CollisionGeometry, pose_a: FloatArray, b: coal.CollisionGeometry,
              pose_b: FloatArray) -> float:  # fmt: skip
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    ta = coal.Transform3s(pose_a[:3, :3], pose_a[:3, 3])
    tb = coal.Transform3s(pose_b[:3, :3], pose_b[:3, 3])
    return float(coal.distance(a, ta, b, tb, request, result))


def _object_near(panda: RobotModel, state: FloatArray, rng: np.random.Generator) -> SceneObject:
    """A box, sphere or cylinder a few centimetres from a random link of the arm."""
    frames = link_transforms(panda, state)[0]
    anchor = frames[rng.integers(1, len(frames)), :3, 3]
    pose = np.eye(4)
    angle = rng.uniform(-math.pi, math.pi)
    pose[:3, :3] = [[math.cos(angle), -math.sin(angle), 0], [math.sin(angle), math.cos(angle), 0],
                    [0, 0, 1]]  # fmt: skip
    pose[:3, 3] = anchor + rng.normal(0.0, 0.1, 3)
    kind = rng.integers(3)
    if kind == 0:
        shape = Shape(ShapeKind.BOX, tuple(rng.uniform(0.01, 0.2, 3)))
    elif kind == 1:
        shape = Shape(ShapeKind.SPHERE, (float(rng.uniform(0.01, 0.08)),))
    else:
        shape = Shape(
            ShapeKind.CYLINDER, (float(rng.uniform(0.01, 0.06)), float(rng.uniform(0.02, 0.3)))
        )
    return SceneObject("thing", shape, pose)


def test_no_compiled_bound_exceeds_the_exact_distance(panda: RobotModel) -> None:
    """A row comes back from the compiled state levels whenever its bound is at most the pad;
    with the pad at coal's exact distance, every row must come back, or a bound exceeded the
    distance (an unsound bound)."""
    rng = np.random.default_rng(5)
    geoms = [_coal(e.shape) for e in panda.elements]
    checked_scene = checked_self = 0
    for _ in range(12):
        state = _states(panda, rng, 1)[0]
        obj = _object_near(panda, state, rng)
        checker = CollisionChecker(panda, make_scene([obj]))
        links = link_transforms(panda, state)[0]
        poses = [links[e.link] @ e.origin for e in panda.elements]
        scene_d = np.array(
            [_distance(g, p, _coal(obj.shape), obj.pose) for g, p in zip(geoms, poses, strict=True)]
        )
        robot = checker.robot
        self_d = np.array(
            [
                _distance(geoms[i], poses[i], geoms[j], poses[j])
                for i, j in zip(robot.pair_i, robot.pair_j, strict=True)
            ]
        )
        tolerance = 1e-9
        verdict = checker.check(
            state[None],
            element_pad=(scene_d + tolerance)[None],
            pair_pad=(self_d + tolerance)[None],
            stop_at_first=False,
            every_contact=True,
        )
        assert verdict.status[0] != COLLIDING or scene_d.min() <= 0.0 or self_d.min() <= 0.0
        rows_scene, rows_self = _rows(checker, state, scene_d + tolerance, self_d + tolerance)
        separated = np.flatnonzero(scene_d > 0.0)
        assert set(separated) <= set(rows_scene), "a scene bound exceeded coal's distance"
        assert set(np.flatnonzero(self_d > 0.0)) <= set(rows_self), "a self bound exceeded it"
        checked_scene += len(separated)
        checked_self += int(np.sum(self_d > 0.0))
    assert checked_scene > 100 and checked_self > 100


def _rows(
    checker: CollisionChecker, state: FloatArray, element_pad: FloatArray, pair_pad: FloatArray
) -> tuple[list[int], list[int]]:
    """The elements and pairs the compiled state levels leave to FCL at these pads."""
    from trajcache.geometry.collision.compiled import state_rows_kernel

    rg = checker.robot
    scene_rows, self_rows = state_rows_kernel(
        checker.pose(state[None]).links,
        rg.kernel_robot,
        rg.element_half,
        rg.support.kernel_args,
        rg.kernel_motion,
        checker.scene.kernel_scene,
        checker.scene.support.kernel_args,
        checker._allowed,
        rg.kernel_pairs,
        np.ascontiguousarray(element_pad[None]),
        np.ascontiguousarray(pair_pad[None]),
    )
    return [int(r[1]) for r in scene_rows], [int(r[1]) for r in self_rows]


def _near_scene(panda: RobotModel, rng: np.random.Generator) -> tuple[Scene, FloatArray]:
    """A few objects around one free state of the arm; the state itself."""
    while True:
        state = _states(panda, rng, 1)[0]
        scene = make_scene(
            [
                SceneObject(f"thing_{k}", o.shape, o.pose)
                for k, o in enumerate(_object_near(panda, state, rng) for _ in range(4))
            ]
        )
        if CollisionChecker(panda, scene).check(state[None]).first_collision < 0:
            return scene, state


def test_certified_never_accepts_what_a_denser_check_rejects_on_the_panda(
    panda: RobotModel,
) -> None:
    rng = np.random.default_rng(11)
    fine = Resolution(0.04 / 20, 0.04 / 20, Resolution().joint_rad / 20)
    outcomes = {"valid": 0, "rejected": 0}
    for _ in range(16):
        scene, start = _near_scene(panda, rng)
        compiled = TrajectoryValidator(panda, scene)
        reference = TrajectoryValidator(panda, scene, certifier=CertifierOptions(compiled=False))
        for _ in range(3):
            goal = np.clip(start + rng.normal(0.0, 0.4, panda.dof), panda.lower, panda.upper)
            key = np.stack([start, goal])
            verdict = compiled.validate(key)
            dense = compiled.checker.check(interpolate(key, panda, fine)).first_collision >= 0
            if verdict.valid:
                outcomes["valid"] += 1
                assert not dense, "certified a motion the dense check finds in collision"
            else:
                outcomes["rejected"] += 1
            # The numpy levels are the reference: a collision one finds, the other finds too.
            if verdict.status is ValidationStatus.COLLISION or reference.validate(key).status is (
                ValidationStatus.COLLISION
            ):
                assert reference.validate(key).status is verdict.status
    assert outcomes["valid"] > 5 and outcomes["rejected"] > 5, outcomes


def test_a_trajectory_that_starts_or_ends_in_collision_is_a_collision(panda: RobotModel) -> None:
    rng = np.random.default_rng(3)
    start, goal = _states(panda, rng, 2)
    hand = link_transforms(panda, start)[0][panda.link_names.index("panda_hand")]
    block = make_scene([SceneObject("block", Shape(ShapeKind.BOX, (0.05, 0.05, 0.05)), hand)])
    validator = TrajectoryValidator(panda, block)
    first = validator.validate(np.stack([start, goal]))
    assert first.status is ValidationStatus.COLLISION, first.message
    assert first.state is not None and np.allclose(first.state, start)  # the first sample
    assert "block" in first.message
    last = validator.validate(np.stack([goal, start]))  # the block is met on the way, or last
    assert last.status is ValidationStatus.COLLISION and "block" in last.message


def test_the_scene_levels_return_every_open_row_however_many(panda: RobotModel) -> None:
    """Inside a box that holds the whole arm, no bound is positive: every (segment, element)
    row is open, thousands of them (the output grows past its first 1,024 rows)."""
    from trajcache.geometry.collision.bodies import Posed
    from trajcache.geometry.model.space import segment_deltas
    from trajcache.geometry.validation.certify import SegmentCertifier

    block = SceneObject("block", Shape(ShapeKind.BOX, (4.0, 4.0, 4.0)), np.eye(4))
    checker = CollisionChecker(panda, make_scene([block]))
    certifier = SegmentCertifier(checker, base=panda.base)
    rng = np.random.default_rng(3)
    states = np.linspace(*_states(panda, rng, 2), 150)
    posed = Posed.build(checker.robot, states)
    step = checker.robot.motion.steps(segment_deltas(states, base=panda.base))
    scene, _ = certifier._compiled_levels(posed, step)
    expected = {(k, e) for k in range(len(states) - 1) for e in range(len(panda.elements))}
    assert len(scene.rows) == len(expected) > 1024
    assert {(int(k), int(e)) for k, e, _ in scene.rows} == expected
    assert np.all(scene.rows[:, 2] == 0) and np.all(scene.lower_a <= 0.0)
    first, _ = certifier._compiled_levels(posed, step, first_only=True)
    assert len(first.rows) == 1
