"""Distance lower bounds: every level stays below the true distance (from sampled surfaces)."""

from __future__ import annotations

import fcl
import numpy as np
import pytest
from scipy.spatial import cKDTree

from tests.robots import BLOCK_URDF
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.reference.restroom import restroom_layout, restroom_scene
from trajcache.reference.robot import reference_model

# A cylinder pose at which FCL 0.7's GJK reports 0.0331 m from the block; the truth is 0.0114 m.
BAD_ROTATION = np.array(
    [
        [-0.14300276, 0.97987978, -0.13923297],
        [-0.77806574, -0.02435764, 0.62771045],
        [0.61168939, 0.19809673, 0.7658941],
    ]
)
BAD_POSITION = np.array([-0.20802729, 0.23387888, -0.08656518])


def _surface(shape: Shape, pose: FloatArray, count: int = 120) -> FloatArray:
    """Points on the surface of a box or cylinder, in the world."""
    if shape.kind is ShapeKind.BOX:
        u = np.linspace(-0.5, 0.5, count)
        a, b = np.meshgrid(u, u)
        faces = []
        for axis in range(3):
            for side in (-0.5, 0.5):
                cols = [a.ravel(), b.ravel()]
                cols.insert(axis, np.full(a.size, side))
                faces.append(np.column_stack(cols))
        local = np.vstack(faces) * np.asarray(shape.size)
    else:
        radius, length = shape.size
        theta, z = np.meshgrid(np.linspace(0, 2 * np.pi, 4 * count), np.linspace(-0.5, 0.5, count))
        side = np.column_stack(
            [radius * np.cos(theta.ravel()), radius * np.sin(theta.ravel()), length * z.ravel()]
        )
        r, th = np.meshgrid(
            np.linspace(0, radius, count // 4), np.linspace(0, 2 * np.pi, 4 * count)
        )
        disk = np.column_stack([r.ravel() * np.cos(th.ravel()), r.ravel() * np.sin(th.ravel())])
        caps = [np.column_stack([disk, np.full(len(disk), h)]) for h in (-length / 2, length / 2)]
        local = np.vstack([side, *caps])
    return np.asarray(local @ pose[:3, :3].T + pose[:3, 3])


def _sampled_distance(a: FloatArray, b: FloatArray) -> float:
    """Smallest distance between two point sets: never below the true distance of the solids."""
    return float(cKDTree(a).query(b)[0].min())


def _box_distance(points: FloatArray, box: SceneObject) -> float:
    """Smallest exact distance from sampled points to a box: never below the solids' distance."""
    local = (points - box.pose[:3, 3]) @ box.pose[:3, :3]
    outside = np.maximum(np.abs(local) - np.asarray(box.shape.size) / 2.0, 0.0)
    return float(np.linalg.norm(outside, axis=1).min())


def test_fcl_distance_is_not_trusted_where_it_is_wrong() -> None:
    model = load_robot_model(BLOCK_URDF)
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = BAD_ROTATION, BAD_POSITION
    cylinder = Shape(ShapeKind.CYLINDER, (0.045, 0.19))
    scene = make_scene([SceneObject("can", cylinder, pose)])
    checker = CollisionChecker(model, scene)
    posed = checker.pose(np.zeros((1, 1)))
    truth = _sampled_distance(
        _surface(model.elements[0].shape, np.eye(4), 200), _surface(cylinder, pose, 200)
    )
    block = fcl.CollisionObject(model.elements[0].shape.to_fcl(), fcl.Transform())
    reported = fcl.distance(
        block, checker.scene.objects[0], fcl.DistanceRequest(), fcl.DistanceResult()
    )
    assert reported > truth + 0.015  # FCL overestimates by about 2 cm here
    cl = checker.clearance
    rows = np.array([[0, 0, 0]])
    spheres = cl.scene_spheres(posed, rows)
    bounds = [
        cl.scene_slabs(posed, rows)[0],
        spheres.lower.min(),
        cl.scene_cover_slabs(posed, rows, spheres)[0],
        checker.narrow.scene_exact(posed, rows)[0],
    ]
    assert all(b <= truth + 1e-9 for b in bounds), bounds
    assert max(bounds) > truth - 0.005  # and the best of them is still close


def _reference_states(model: RobotModel, rng: np.random.Generator, count: int) -> FloatArray:
    stations = np.array([s.pose for s in restroom_layout().stations])
    base = stations[rng.integers(len(stations), size=count)]
    off = model.arm_offset
    lower, upper = np.maximum(model.lower[off:], -np.pi), np.minimum(model.upper[off:], np.pi)
    arm = rng.uniform(lower, upper, size=(count, model.dof - off))
    return np.hstack([base, arm])


@pytest.fixture(scope="module")
def restroom() -> tuple[RobotModel, Scene, CollisionChecker]:
    model = reference_model()
    scene = restroom_scene(doors=(20, 60, 90), seats=(0, 90, 0))
    return model, scene, CollisionChecker(model, scene)


def test_scene_bounds_stay_below_the_sampled_distance(restroom) -> None:  # type: ignore[no-untyped-def]
    model, scene, checker = restroom
    cl = checker.clearance
    posed = checker.pose(_reference_states(model, np.random.default_rng(4), 300))
    near = cl.near_objects(posed, np.full(posed.centres.shape[:2], 0.05))
    balls = cl.scene_balls(posed, near)
    rows = np.argwhere((balls < 0.05) & (balls > 0.0))
    rows[:, 2] = near[rows[:, 2]]
    boxes = np.array([scene.objects[m].shape.kind is ShapeKind.BOX for m in rows[:, 2]])
    rows = rows[
        boxes
        & np.isin(
            rows[:, 1],
            np.flatnonzero(
                [e.shape.kind in (ShapeKind.BOX, ShapeKind.CYLINDER) for e in model.elements]
            ),
        )
    ][:40]
    assert len(rows) >= 20
    spheres = cl.scene_spheres(posed, rows)
    levels = [
        np.maximum(balls[rows[:, 0], rows[:, 1], np.searchsorted(near, rows[:, 2])], 0.0),
        cl.scene_slabs(posed, rows),
        np.maximum(spheres.lower.min(axis=1), 0.0),
        cl.scene_cover_slabs(posed, rows, spheres),
        checker.narrow.scene_exact(posed, rows),
    ]
    for k, (sample, element, obj) in enumerate(rows):
        pose = posed.pose(np.array([sample]), np.array([element]))[0]
        truth = _box_distance(_surface(model.elements[element].shape, pose, 80), scene.objects[obj])
        for level, bound in enumerate(levels):
            assert bound[k] <= truth + 1e-9, (level, bound[k], truth)
        assert levels[-1][k] > truth - 0.003 or truth == 0.0  # exact, less its margin


def test_self_bounds_stay_below_the_sampled_distance(restroom) -> None:  # type: ignore[no-untyped-def]
    model, _scene, checker = restroom
    cl = checker.clearance
    rg = checker.robot
    posed = checker.pose(_reference_states(model, np.random.default_rng(5), 300))
    gaps = cl.self_balls(posed)
    rows = np.argwhere((gaps < 0.04) & (gaps > -0.2))
    cylinders = np.array(
        [
            model.elements[rg.pair_i[p]].shape.kind is ShapeKind.CYLINDER
            and model.elements[rg.pair_j[p]].shape.kind is ShapeKind.CYLINDER
            for p in rows[:, 1]
        ]
    )
    rows = rows[cylinders][:30]
    assert len(rows) >= 20
    spheres = cl.self_spheres(posed, rows)
    levels = [
        cl.self_slabs(posed, rows),
        np.maximum(spheres.lower.min(axis=(1, 2)), 0.0),
        cl.self_cover_slabs(posed, rows, spheres),
        checker.narrow.self_exact(posed, rows),
    ]
    for k, (sample, pair) in enumerate(rows):
        ei, ej = rg.pair_i[pair], rg.pair_j[pair]
        at = np.array([sample])
        truth = _sampled_distance(
            _surface(model.elements[ei].shape, posed.pose(at, np.array([ei]))[0], 50),
            _surface(model.elements[ej].shape, posed.pose(at, np.array([ej]))[0], 50),
        )
        for level, bound in enumerate(levels):
            assert bound[k] <= truth + 1e-9, (level, bound[k], truth)
