"""The compiled exact level: GJK lower bounds against coal, and the triangles of concave meshes."""

from __future__ import annotations

import coal
import numpy as np
import pytest
import trimesh

from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.collision.compiled.gjk import convex_lower_rows
from trajcache.geometry.collision.narrow import EXACT_MARGIN
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind, pose_matrix
from trajcache.geometry.model.support import SupportTable
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import SceneObject, make_scene

BALL_URDF = """<robot name="ball">
  <link name="base"><collision><geometry><sphere radius="0.02"/></geometry></collision></link>
</robot>"""


def _shape(rng: np.random.Generator, kind: int) -> Shape:
    if kind == 0:
        return Shape(ShapeKind.BOX, tuple(rng.uniform(0.02, 0.3, 3)))
    if kind == 1:
        return Shape(ShapeKind.SPHERE, (rng.uniform(0.01, 0.2),))
    if kind == 2:
        return Shape(ShapeKind.CYLINDER, tuple(rng.uniform(0.01, 0.3, 2)))
    if kind == 3:
        return Shape(ShapeKind.CAPSULE, tuple(rng.uniform(0.01, 0.3, 2)))
    if kind == 4:  # a convex mesh, stretched and off its origin
        mesh = trimesh.creation.icosphere(1, radius=rng.uniform(0.05, 0.2))
        vertices = mesh.vertices * rng.uniform(0.5, 1.5, 3) + rng.uniform(-0.05, 0.05, 3)
        return Shape(ShapeKind.MESH, vertices=np.asarray(vertices), faces=np.asarray(mesh.faces))
    return _u_shape(rng.uniform(0.05, 0.2))  # concave: bounded as its hull


def _u_shape(size: float) -> Shape:
    """A U of three boxes (concave; its notch, between the arms, is inside its hull)."""
    parts = [
        trimesh.creation.box((size, size / 4, size / 4), _moved(0, -size * 3 / 8, 0)),
        trimesh.creation.box((size / 4, size, size / 4), _moved(-size * 3 / 8, 0, 0)),
        trimesh.creation.box((size, size / 4, size / 4), _moved(0, size * 3 / 8, 0)),
    ]
    mesh = trimesh.util.concatenate(parts)
    return Shape(ShapeKind.MESH, vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces))


def _moved(x: float, y: float, z: float) -> FloatArray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


def _poses(rng: np.random.Generator, count: int, reach: float) -> FloatArray:
    quats = rng.normal(size=(count, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    return np.array([pose_matrix(rng.uniform(-reach, reach, 3), q) for q in quats])


def _coal_hull(shape: Shape) -> coal.CollisionGeometry:
    return shape.to_coal_hull(shape.to_coal())


def _random_rows(seed: int, count: int) -> tuple:  # type: ignore[type-arg]
    rng = np.random.default_rng(seed)
    shapes_a = [_shape(rng, k % 6) for k in range(36)]
    shapes_b = [_shape(rng, (k + 3) % 6) for k in range(36)]
    index_a = rng.integers(len(shapes_a), size=count)
    index_b = rng.integers(len(shapes_b), size=count)
    poses_a, poses_b = _poses(rng, count, 0.35), _poses(rng, count, 0.35)
    request = coal.DistanceRequest()
    hulls_a, hulls_b = [_coal_hull(s) for s in shapes_a], [_coal_hull(s) for s in shapes_b]
    truth = np.empty(count)
    for k, (a, b, pa, pb) in enumerate(zip(index_a, index_b, poses_a, poses_b, strict=True)):
        truth[k] = coal.distance(
            hulls_a[a], coal.Transform3s(pa[:3, :3], pa[:3, 3]),
            hulls_b[b], coal.Transform3s(pb[:3, :3], pb[:3, 3]),
            request, coal.DistanceResult(),
        )  # fmt: skip
    tables = (SupportTable.build(shapes_a), SupportTable.build(shapes_b))
    return tables, index_a, index_b, poses_a, poses_b, truth


def _lower(rows: tuple, need: FloatArray) -> FloatArray:  # type: ignore[type-arg]
    (table_a, table_b), index_a, index_b, poses_a, poses_b, _ = rows
    out = np.empty(len(index_a))
    convex_lower_rows(
        poses_a, table_a.kernel_args, index_a, poses_b, table_b.kernel_args, index_b,
        np.ascontiguousarray(need, dtype=float), np.empty((4, 3)), out,
    )  # fmt: skip
    return out


@pytest.fixture(scope="module")
def rows() -> tuple:  # type: ignore[type-arg]
    return _random_rows(11, 2000)


def test_the_bound_never_exceeds_coals_distance_and_meets_it(rows) -> None:  # type: ignore[no-untyped-def]
    truth = rows[-1]
    lower = _lower(rows, np.full(len(truth), np.inf))
    apart = truth > 1e-6
    assert apart.sum() > 1000 and (~apart).sum() > 200  # both kinds of rows are exercised
    # A proved bound: never above the distance (coal's own answer is within 1e-6 of it).
    assert np.all(lower <= np.maximum(truth, 0.0) + 1e-6)
    # And tight: run to convergence it is the distance, to well under the exact margin.
    assert np.all(lower[apart] >= truth[apart] - EXACT_MARGIN / 2)
    assert np.all(lower[~apart] <= 1e-6)  # overlapping or touching: nothing to bound


def test_the_search_stops_once_the_bound_exceeds_what_is_needed(rows) -> None:  # type: ignore[no-untyped-def]
    truth = rows[-1]
    need = np.where(truth > 0.01, truth / 2, np.inf)
    lower = _lower(rows, need)
    cut = truth > 0.01
    assert np.all(lower[cut] > need[cut])
    assert np.all(lower <= np.maximum(truth, 0.0) + 1e-6)
    # Stopped early, the bound is often well short of the distance.
    assert np.mean(lower[cut] < truth[cut] - 1e-4) > 0.2


def test_a_concave_mesh_is_measured_as_its_triangles_where_its_hull_falls_short() -> None:
    # A ball (radius 0.02) at the centre of a U of size 0.2: inside the U's hull, 0.05 from
    # the inner faces of its arms and its back.
    scene = make_scene([SceneObject("u", _u_shape(0.2), np.eye(4))])
    checker = CollisionChecker(load_robot_model(BALL_URDF), scene)
    posed = checker.pose(np.zeros((1, checker.model.dof)))
    rows = np.array([[0, 0, 0]])
    assert checker.narrow.scene_exact(posed, rows)[0] == pytest.approx(
        0.05 - 0.02 - EXACT_MARGIN, abs=1e-6
    )
    # Needing little still measures it: the hull's bound, 0, is not above any need.
    assert checker.narrow.scene_exact(posed, rows, np.array([0.001]))[0] > 0.001
    # The U's hull strays 0.05 from it (the middle of its open side, between the arms): a
    # certifier needing more than that gets the hull's bound, as the triangles cannot lift it
    # past the need, and needing less, the triangles'.
    gap = checker.narrow.scene.gaps[0]
    assert gap == pytest.approx(0.05, abs=0.002)
    for need, bound in ((0.2, -EXACT_MARGIN), (0.04, 0.03 - EXACT_MARGIN)):
        got = checker.narrow.scene_exact(posed, rows, np.array([need]), past_need=True)
        assert got[0] == pytest.approx(bound, abs=1e-6)
    # A convex mesh is bounded as itself: the ball beside a box-shaped mesh.
    box = trimesh.creation.box((0.1, 0.1, 0.1))
    mesh = Shape(ShapeKind.MESH, vertices=np.asarray(box.vertices), faces=np.asarray(box.faces))
    scene = make_scene([SceneObject("box", mesh, _moved(0.1, 0.0, 0.0))])
    checker = CollisionChecker(load_robot_model(BALL_URDF), scene)
    assert checker.narrow.scene.gaps[0] < 1e-9
    posed = checker.pose(np.zeros((1, checker.model.dof)))
    assert checker.narrow.scene_exact(posed, rows)[0] == pytest.approx(
        0.05 - 0.02 - EXACT_MARGIN, abs=1e-6
    )
