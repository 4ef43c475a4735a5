"""Support functions and sphere covers of collision shapes, the raw material of distance bounds.

Every primitive is a Minkowski sum, about a local centre c, of an axis-aligned box (half extents
b), a disk of radius r_d in the local xy plane and a ball of radius r_b: a box is (b, 0, 0), a
cylinder (0, 0, L/2; r, 0), a capsule (0, 0, L/2; 0, r), a sphere (0; 0, r). Support functions
add over Minkowski sums, so for a unit local direction n

    h(n) = max over the shape of n·x = n·c + |n|·b + r_d·|n_xy| + r_b

in one vectorized expression for any mix of shapes. A mesh uses its convex hull's vertices
(h(n) = max over hull vertices of n·v), which bounds the mesh from outside. For any unit world
direction n and shapes A, B posed at (R_A, t_A), (R_B, t_B),

    dist(A, B) ≥ n·t_B − h_B(−R_Bᵀ n) − n·t_A − h_A(R_Aᵀ n)

(a separating slab of that width), whatever n is; a good n makes it tight.

A sphere cover is a set of balls whose union contains the shape, used for cheap vectorized
bounds: dist(ball, X) ≥ dist(centre, X) − radius.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import ConvexHull, QhullError

from trajcache.geometry.model.kernels import hull_support_climb
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind

IntArray = NDArray[np.int64]

# A cylinder is cut into slabs no longer than one radius (each slab's ball is then at most
# √(1 + 0.5²) ≈ 1.12 radii), and into no more than _MAX_SLABS slabs.
_SLAB_RADII = 1.0
_MAX_SLABS = 12
_BOX_CELLS = 3  # a box is cut into at most this many cells along its longest side
_EPS = 1e-9  # grows covers and shrinks nothing: round-off never makes a bound unsound


@dataclass(frozen=True)
class SupportTable:
    """Support parameters of an indexed list of shapes (arrays over the shapes)."""

    centre: FloatArray  # (K, 3)
    half: FloatArray  # (K, 3) box part
    disk: FloatArray  # (K,)
    ball: FloatArray  # (K,)
    hulls: tuple[FloatArray | None, ...]  # hull vertices of meshes, None for primitives
    packed: FloatArray  # (K, 5): half, disk, ball, gathered in one go
    has_centres: bool
    has_hulls: bool
    # Every hull's vertices packed for the compiled kernel: shape k's hull is
    # hull_vertices[hull_start[k] : hull_start[k] + hull_count[k]]; hull_slot[k] is k for a mesh
    # and -1 for a primitive.
    hull_vertices: FloatArray
    hull_start: IntArray
    hull_count: IntArray
    hull_slot: IntArray
    # For hill climbing (`kernels.hull_support_climb`): each hull's anchor vertices, and the
    # vertices that share a hull edge with each packed vertex (CSR), all as packed indices.
    anchors: IntArray
    anchor_start: IntArray
    anchor_count: IntArray
    neighbours: IntArray
    neighbour_start: IntArray

    @classmethod
    def build(cls, shapes: Sequence[Shape]) -> SupportTable:
        """The table of `shapes`, in order."""
        params = [_params(s) for s in shapes]
        count = len(params)
        centre = np.array([p[0] for p in params], dtype=float).reshape(count, 3)
        half = np.array([p[1] for p in params], dtype=float).reshape(count, 3)
        disk = np.array([p[2] for p in params], dtype=float).reshape(count)
        ball = np.array([p[3] for p in params], dtype=float).reshape(count)
        hulls = [p[4] for p in params]
        sizes = np.array([0 if h is None else len(h) for h in hulls], dtype=np.int64)
        packed_hulls = [h for h in hulls if h is not None]
        starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        graphs = [_hull_graph(h) if h is not None else None for h in hulls]
        anchors = [starts[k] + g[0] for k, g in enumerate(graphs) if g is not None]
        lists = [
            [starts[k] + n for n in around]
            for k, g in enumerate(graphs)
            if g is not None
            for around in g[1]
        ]
        return cls(
            centre=centre,
            half=half,
            disk=disk,
            ball=ball,
            hulls=tuple(p[4] for p in params),
            packed=np.column_stack([half, disk, ball]),
            has_centres=bool(np.any(centre)),
            has_hulls=any(p[4] is not None for p in params),
            hull_vertices=np.ascontiguousarray(
                np.concatenate(packed_hulls) if packed_hulls else np.zeros((0, 3))
            ),
            hull_start=starts,
            hull_count=sizes,
            hull_slot=np.array(
                [k if h is not None else -1 for k, h in enumerate(hulls)], dtype=np.int64
            ),
            anchors=np.concatenate(anchors or [np.zeros(0)]).astype(np.int64),
            anchor_start=np.array(
                _offsets([0 if g is None else len(g[0]) for g in graphs]), dtype=np.int64
            ),
            anchor_count=np.array([0 if g is None else len(g[0]) for g in graphs], np.int64),
            neighbours=np.array([n for around in lists for n in around], dtype=np.int64),
            neighbour_start=np.array(_offsets([len(a) for a in lists], total=True), np.int64),
        )

    def support(self, index: IntArray, local: FloatArray, *, exact: bool = True) -> FloatArray:
        """h(n) for unit local directions `local` (..., 3) of the shapes `index` (...).

        Not `exact`: a mesh's is its bounding box's, an upper bound that costs no hull query.
        """
        p = self.packed[index]
        x, y, z = local[..., 0], local[..., 1], local[..., 2]
        value = (
            np.abs(x) * p[..., 0]
            + np.abs(y) * p[..., 1]
            + np.abs(z) * p[..., 2]
            + p[..., 3] * np.sqrt(x * x + y * y)
            + p[..., 4]
        )
        if self.has_centres:
            c = self.centre[index]
            value += x * c[..., 0] + y * c[..., 1] + z * c[..., 2]
        if exact and self.has_hulls:  # a mesh: the largest projection of its hull (compiled)
            shape = value.shape
            slot = self.hull_slot[np.broadcast_to(index, local.shape[:-1]).ravel()]
            flat = np.ascontiguousarray(value, dtype=float).reshape(-1)
            directions = np.ascontiguousarray(local, dtype=float).reshape(-1, 3)
            hull_support_climb(
                self.hull_vertices,
                self.hull_start,
                self.hull_count,
                self.anchors,
                self.anchor_start,
                self.anchor_count,
                self.neighbours,
                self.neighbour_start,
                slot,
                directions,
                flat,
            )
            value = flat.reshape(shape)
        return np.asarray(value)

    @functools.cached_property
    def kernel_args(self) -> tuple[np.ndarray, ...]:
        """The table as the compiled kernels take it (`collision/compiled/slabs.support_at`)."""
        return (
            np.ascontiguousarray(self.centre, dtype=float),
            np.ascontiguousarray(self.packed, dtype=float),
            self.hull_slot,
            self.hull_vertices,
            self.anchors,
            self.anchor_start,
            self.anchor_count,
            self.neighbours,
            self.neighbour_start,
        )

    def coarse(self, index: IntArray, local: FloatArray) -> FloatArray:
        """`support` with meshes bounded by their boxes (cheap, looser, still an upper bound)."""
        return self.support(index, local, exact=False)


def _params(shape: Shape) -> tuple[FloatArray, FloatArray, float, float, FloatArray | None]:
    zero = np.zeros(3)
    if shape.kind is ShapeKind.BOX:
        return zero, np.asarray(shape.size, dtype=float) / 2.0, 0.0, 0.0, None
    if shape.kind is ShapeKind.SPHERE:
        return zero, zero, 0.0, shape.size[0], None
    if shape.kind in (ShapeKind.CYLINDER, ShapeKind.CAPSULE):
        radius, length = shape.size
        half = np.array([0.0, 0.0, length / 2.0])
        if shape.kind is ShapeKind.CYLINDER:
            return zero, half, radius, 0.0, None
        return zero, half, 0.0, radius, None
    assert shape.vertices is not None
    lo, hi = _mesh_box(shape)
    return (lo + hi) / 2.0, (hi - lo) / 2.0, 0.0, 0.0, _hull(shape.vertices)


def _mesh_box(shape: Shape) -> tuple[FloatArray, FloatArray]:
    assert shape.vertices is not None
    verts = np.asarray(shape.vertices, dtype=float)
    return verts.min(axis=0), verts.max(axis=0)


def _hull(vertices: FloatArray) -> FloatArray:
    """Vertices of the convex hull (all vertices when the hull is degenerate, e.g. flat)."""
    verts = np.asarray(vertices, dtype=float)
    try:
        return verts[ConvexHull(verts).vertices]
    except QhullError:  # flat or tiny point sets: every vertex still gives the same support
        return verts


_ANCHOR_DIRECTIONS = np.array(
    [
        [x, y, z]
        for x in (-1, 0, 1)
        for y in (-1, 0, 1)
        for z in (-1, 0, 1)
        if (x, y, z) != (0, 0, 0)
    ],
    dtype=float,
)


def _hull_graph(vertices: FloatArray) -> tuple[IntArray, list[list[int]]]:
    """Anchor vertices (the extreme ones along 26 directions) and, per vertex, the vertices that
    share an edge of the hull's triangulated faces. A flat point set (no 3-D hull) gets every
    vertex as an anchor and no edges, so the climb is the plain maximum."""
    count = len(vertices)
    try:
        simplices = ConvexHull(vertices).simplices
    except QhullError:
        return np.arange(count, dtype=np.int64), [[] for _ in range(count)]
    around: list[set[int]] = [set() for _ in range(count)]
    for a, b, c in simplices:
        around[a].update((b, c))
        around[b].update((a, c))
        around[c].update((a, b))
    anchors = np.unique(np.argmax(_ANCHOR_DIRECTIONS @ vertices.T, axis=1))
    return anchors.astype(np.int64), [sorted(n) for n in around]


def _offsets(sizes: Sequence[int], *, total: bool = False) -> list[int]:
    """Start of each block of `sizes` packed one after another (and the end, with `total`)."""
    starts = [0]
    for size in sizes:
        starts.append(starts[-1] + size)
    return starts if total else starts[:-1]


def sphere_cover(shape: Shape, cells: int = _BOX_CELLS) -> tuple[FloatArray, FloatArray]:
    """Centres (k, 3) and radii (k,) of balls whose union contains the shape (local frame); a
    box or mesh is cut into at most `cells` cells along its longest side."""
    if shape.kind is ShapeKind.SPHERE:
        return np.zeros((1, 3)), np.array([shape.size[0] + _EPS])
    if shape.kind in (ShapeKind.CYLINDER, ShapeKind.CAPSULE):
        radius, length = shape.size
        if shape.kind is ShapeKind.CAPSULE:
            length += 2.0 * radius  # a capsule lies inside the cylinder through its cap tips
        count = min(max(1, math.ceil(length / (_SLAB_RADII * radius))), _MAX_SLABS)
        slab = length / count
        z = -length / 2.0 + slab * (np.arange(count) + 0.5)
        centres = np.column_stack([np.zeros(count), np.zeros(count), z])
        return centres, np.full(count, math.hypot(radius, slab / 2.0) + _EPS)
    if shape.kind is ShapeKind.BOX:
        centres, step = _grid(-np.asarray(shape.size) / 2.0, np.asarray(shape.size) / 2.0, cells)
        return centres, np.full(len(centres), float(np.linalg.norm(step)) / 2.0 + _EPS)
    assert shape.vertices is not None and shape.faces is not None
    centres, step = _grid(*_mesh_box(shape), cells)
    centres = centres[_cells_of_mesh(centres, step / 2.0, shape.vertices, shape.faces)]
    return centres, np.full(len(centres), float(np.linalg.norm(step)) / 2.0 + _EPS)


def _grid(lo: FloatArray, hi: FloatArray, cells: int) -> tuple[FloatArray, FloatArray]:
    """Centres (C, 3) and the common size (3,) of the cells a box [lo, hi] is cut into."""
    size = hi - lo
    cell = max(float(size.max()) / cells, 1e-9)
    counts = np.maximum(np.ceil(size / cell - 1e-9).astype(int), 1)
    step = size / counts
    axes = [lo[i] + step[i] * (np.arange(counts[i]) + 0.5) for i in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3), step


def _cells_of_mesh(
    centres: FloatArray, half: FloatArray, vertices: FloatArray, faces: IntArray
) -> NDArray[np.bool_]:
    """Which grid cells (centres (C, 3), half extents (3,)) a mesh needs in its cover.

    A cell is kept when a triangle may cross it: the triangle's box overlaps the cell and its
    plane passes within the cell's reach (both are necessary for an overlap, so no crossed
    cell is dropped). A cell no triangle crosses lies wholly inside or wholly outside the
    mesh's solid; it is kept when its centre is inside, by the generalized winding number,
    which counts overlapping closed parts right, where a ray's parity does not. What is left
    covers every point of the mesh, surface and solid.
    """
    tri = np.asarray(vertices, dtype=float)[np.asarray(faces, dtype=np.int64)]  # (F, 3, 3)
    reach = np.asarray(half, dtype=float) * (1.0 + 1e-9) + _EPS
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # (F, 3)
    offset = np.einsum("fi,fi->f", normal, tri[:, 0])
    radius = np.abs(normal) @ reach
    low, high = tri.min(axis=1), tri.max(axis=1)
    crossed = np.zeros(len(centres), dtype=bool)
    for c, centre in enumerate(centres):
        boxes = np.all((low <= centre + reach) & (high >= centre - reach), axis=1)
        plane = np.abs(normal[boxes] @ centre - offset[boxes]) <= radius[boxes] * (1.0 + 1e-9)
        crossed[c] = bool(plane.any())
    keep = crossed.copy()
    keep[~crossed] = np.abs(_winding_numbers(centres[~crossed], tri)) >= 0.5
    return keep


def _winding_numbers(points: FloatArray, tri: FloatArray) -> FloatArray:
    """Generalized winding number of each point (P, 3) for triangles (F, 3, 3): the sum of
    their signed solid angles over 4π (Van Oosterom and Strackee's formula)."""
    out = np.zeros(len(points))
    for k, point in enumerate(points):
        a, b, c = (tri[:, i] - point for i in range(3))
        la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
        det = np.einsum("fi,fi->f", a, np.cross(b, c))
        dots = (
            la * lb * lc
            + np.einsum("fi,fi->f", a, b) * lc
            + np.einsum("fi,fi->f", b, c) * la
            + np.einsum("fi,fi->f", c, a) * lb
        )
        out[k] = float(np.sum(2.0 * np.arctan2(det, dots)) / (4.0 * np.pi))
    return out
