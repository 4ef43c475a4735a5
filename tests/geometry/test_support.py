"""Support functions and sphere covers of the collision primitives, against sampled surfaces."""

from __future__ import annotations

import numpy as np
import pytest

from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.support import SupportTable, sphere_cover

TETRA = Shape(
    ShapeKind.MESH,
    vertices=np.array([[0.1, 0.0, 0.0], [0.3, 0.0, 0.0], [0.1, 0.2, 0.0], [0.1, 0.0, 0.25]]),
    faces=np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]),
)
SHAPES = {
    "box": Shape(ShapeKind.BOX, (0.3, 0.1, 0.2)),
    "sphere": Shape(ShapeKind.SPHERE, (0.07,)),
    "cylinder": Shape(ShapeKind.CYLINDER, (0.04, 0.3)),
    "capsule": Shape(ShapeKind.CAPSULE, (0.03, 0.2)),
    "mesh": TETRA,
}


def _inside(shape: Shape, rng: np.random.Generator, count: int) -> FloatArray:
    """Random points of the solid (on and inside its boundary), in its own frame."""
    u = rng.uniform(-1.0, 1.0, size=(count, 3))
    u[: count // 4] = np.sign(u[: count // 4])  # box corners, cylinder rims
    if shape.kind is ShapeKind.BOX:
        return u * np.asarray(shape.size) / 2.0
    if shape.kind is ShapeKind.SPHERE:
        return u / np.maximum(np.linalg.norm(u, axis=1), 1.0)[:, None] * shape.size[0]
    if shape.kind in (ShapeKind.CYLINDER, ShapeKind.CAPSULE):
        radius, length = shape.size
        disk = u[:, :2] / np.maximum(np.linalg.norm(u[:, :2], axis=1), 1.0)[:, None] * radius
        z = u[:, 2] * length / 2.0
        points = np.column_stack([disk, z])
        if shape.kind is ShapeKind.CAPSULE:  # add the caps: balls at both segment ends
            ball = u / np.maximum(np.linalg.norm(u, axis=1), 1.0)[:, None] * radius
            ends = np.where(rng.random(count) < 0.5, -1.0, 1.0) * length / 2.0
            caps = ball + np.column_stack([np.zeros(count), np.zeros(count), ends])
            points = np.vstack([points, caps])
        return points
    assert shape.vertices is not None
    weights = rng.dirichlet(np.ones(len(shape.vertices)), size=count)
    return np.vstack([weights @ shape.vertices, shape.vertices])


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_support_is_the_largest_extent_along_each_direction(name: str) -> None:
    shape = SHAPES[name]
    rng = np.random.default_rng(1)
    points = _inside(shape, rng, 20_000)
    dirs = rng.normal(size=(200, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    support = SupportTable.build([shape]).support(np.zeros(200, dtype=np.int64), dirs)
    sampled = (dirs @ points.T).max(axis=1)
    assert np.all(support >= sampled - 1e-12)  # an upper bound: no point sticks out
    assert np.all(support <= sampled + 0.02)  # and a tight one (sampling leaves small gaps)


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_sphere_cover_contains_the_shape(name: str) -> None:
    shape = SHAPES[name]
    centres, radii = sphere_cover(shape)
    points = _inside(shape, np.random.default_rng(2), 20_000)
    gap = np.linalg.norm(points[:, None] - centres[None], axis=-1) - radii[None]
    assert np.all(gap.min(axis=1) <= 0.0)
    if shape.kind in (ShapeKind.CYLINDER, ShapeKind.CAPSULE):  # slabs: never much fatter
        assert radii.max() <= 1.2 * shape.size[0]


def test_a_mixed_table_indexes_each_shape() -> None:
    shapes = [SHAPES["box"], SHAPES["cylinder"], SHAPES["mesh"], SHAPES["sphere"]]
    table = SupportTable.build(shapes)
    assert table.has_hulls
    dirs = np.array([[[1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]] * 4)  # (4 shapes, 2 directions, 3)
    value = table.support(np.arange(4)[:, None], dirs)
    np.testing.assert_allclose(value[0], [0.15, 0.1])
    np.testing.assert_allclose(value[1], [0.04, 0.15])
    np.testing.assert_allclose(value[2], [0.3, 0.0])
    np.testing.assert_allclose(value[3], [0.07, 0.07])


def test_the_compiled_mesh_support_is_the_largest_projection_of_its_hull() -> None:
    rng = np.random.default_rng(3)
    meshes = []
    for count in (30, 200, 7):
        vertices = rng.normal(size=(count, 3)) * [0.1, 0.05, 0.2] + rng.normal(size=3)
        meshes.append(Shape(ShapeKind.MESH, (), vertices=vertices, faces=np.zeros((1, 3), int)))
    shapes = [meshes[0], Shape(ShapeKind.BOX, (0.1, 0.2, 0.3)), meshes[1], meshes[2]]
    table = SupportTable.build(shapes)
    index = rng.integers(0, len(shapes), size=(500, 4))
    local = rng.normal(size=(500, 4, 3))
    local /= np.linalg.norm(local, axis=-1, keepdims=True)
    got = table.support(index, local)
    for k, shape in enumerate(shapes):
        rows = index == k
        if shape.kind is ShapeKind.MESH:
            assert shape.vertices is not None
            want = (local[rows] @ shape.vertices.T).max(axis=-1)  # hull vertices hold the max
        else:
            want = SupportTable.build([shape]).support(np.zeros(rows.sum(), int), local[rows])
        np.testing.assert_allclose(got[rows], want, rtol=0, atol=1e-12)


@pytest.mark.parametrize("robot", ["kinova", "panda", "tiago"])
def test_hill_climbing_finds_the_largest_projection_on_real_meshes(robot: str) -> None:
    from trajcache.geometry.model.urdf import load_robot_model
    from trajcache.reference.example_robots import ROBOTS

    example = ROBOTS[robot]
    model = load_robot_model(example.urdf, files=example.files(), joint_names=example.joint_names,
                             srdf=example.srdf, group=example.group)  # fmt: skip
    meshes = [e.shape for e in model.elements if e.shape.kind is ShapeKind.MESH]
    table = SupportTable.build(meshes)
    rng = np.random.default_rng(5)
    local = rng.normal(size=(len(meshes), 2000, 3))
    local /= np.linalg.norm(local, axis=-1, keepdims=True)
    got = table.support(np.arange(len(meshes))[:, None], local)
    for k, shape in enumerate(meshes):
        assert shape.vertices is not None
        want = (local[k] @ shape.vertices.T).max(axis=-1)
        np.testing.assert_allclose(got[k], want, rtol=0, atol=1e-12)


def _mesh(*boxes: tuple[tuple[float, float, float], tuple[float, float, float]]) -> Shape:
    """One mesh of the triangles of several boxes (extents, centre), overlaps left in."""
    import trimesh

    parts = []
    for extents, centre in boxes:
        pose = np.eye(4)
        pose[:3, 3] = centre
        parts.append(trimesh.creation.box(extents, pose))
    mesh = trimesh.util.concatenate(parts)
    return Shape(ShapeKind.MESH, vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces))


def _points_of(shape: Shape, boxes: list[tuple[FloatArray, FloatArray]], count: int) -> FloatArray:
    """Points on the surface of a mesh made by `_mesh` and inside its boxes (lo, hi)."""
    import trimesh

    assert shape.vertices is not None
    mesh = trimesh.Trimesh(shape.vertices, shape.faces, process=False)
    surface = trimesh.sample.sample_surface(mesh, count, seed=3)[0]
    rng = np.random.default_rng(3)
    solid = [rng.uniform(lo, hi, size=(count, 3)) for lo, hi in boxes]
    return np.vstack([surface, *solid])


def test_a_mesh_cover_drops_the_cells_the_mesh_leaves_empty() -> None:
    ell = _mesh(((0.3, 0.03, 0.03), (0.15, 0.015, 0.0)), ((0.03, 0.3, 0.03), (0.015, 0.15, 0.0)))
    centres, radii = sphere_cover(ell)
    assert len(centres) == 5  # of the 3 × 3 grid's 9 cells, the L crosses 5
    boxes = [(np.array([0.0, 0.0, -0.015]), np.array([0.3, 0.03, 0.015])),
             (np.array([0.0, 0.0, -0.015]), np.array([0.03, 0.3, 0.015]))]  # fmt: skip
    points = _points_of(ell, boxes, 4000)
    gap = np.linalg.norm(points[:, None] - centres[None], axis=-1) - radii[None]
    assert np.all(gap.min(axis=1) <= 0.0)


def test_a_mesh_cover_keeps_cells_inside_overlapping_parts() -> None:
    # Two closed cubes, one just inside the other: the middle cell touches neither surface and
    # lies inside both, where a ray's parity would call it outside.
    nested = _mesh(((0.3, 0.3, 0.3), (0.0, 0.0, 0.0)), ((0.29, 0.29, 0.29), (0.0, 0.0, 0.0)))
    centres, _ = sphere_cover(nested)
    assert len(centres) == 27
    assert np.min(np.linalg.norm(centres, axis=1)) < 1e-9


def test_a_hull_gap_is_how_far_a_meshs_hull_strays_from_its_triangles() -> None:
    cube = _mesh(((0.2, 0.2, 0.2), (0.0, 0.0, 0.0)))
    ell = _mesh(((0.3, 0.03, 0.03), (0.15, 0.015, 0.0)), ((0.03, 0.3, 0.03), (0.015, 0.15, 0.0)))
    assert cube.hull_gap() < 1e-9 and SHAPES["box"].hull_gap() == 0.0
    # The L's hull spans its notch: the middle of the hull's slanted face, (0.165, 0.165) in
    # the plane, is farthest from the L, 0.135 from both arms (their inner faces at 0.03).
    assert ell.hull_gap() == pytest.approx(0.135, abs=0.005)
    open_mesh = Shape(ShapeKind.MESH, vertices=TETRA.vertices, faces=TETRA.faces[:3])
    assert open_mesh.hull_gap() > 0.0  # the missing face is the hull's, not the mesh's
    flat = Shape(ShapeKind.MESH, vertices=TETRA.vertices[:3], faces=TETRA.faces[:1])
    assert flat.hull_gap() == np.inf  # no 3-D hull: always measured as its triangles
