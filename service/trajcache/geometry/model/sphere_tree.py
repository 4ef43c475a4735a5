"""Sphere trees of collision shapes: balls whose leaves hug a mesh's surface, for planners.

A mesh's tree is an octree of the cubes its surface may cross, from the cube around its
vertices down to cubes of side at most `leaf` (by default 6 mm); each node is the ball
circumscribing its cube. A cube is kept when some triangle may cross it: the triangle's box
overlaps the cube and its plane passes within the cube's reach. Both are necessary for a
triangle to meet the cube, so no crossed cube is dropped, and every point of every triangle
lies in a kept leaf cube, so in its ball, and in the ball of every ancestor (a parent's cube
holds its children's). FCL tests a mesh as its triangles, so the leaves cover all it tests.

Each leaf also keeps its reach: the exact distance from its centre to the nearest triangle
(trimesh, grown by a micrometre). A centre deeper than its reach inside a solid object proves
that a triangle point, the nearest one, lies inside the object.

A primitive is a solid for FCL: its tree is its bounding ball over the balls of its sphere
cover (`support.sphere_cover`), whose centres lie inside it (reach 0).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import NDArray

from trajcache.geometry.disk_cache import cached_arrays, digest
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.support import sphere_cover

IntArray = NDArray[np.int64]
LEAF_M = 0.008  # side of a leaf cube
_PRIMITIVE_CELLS = 8  # most cells along a primitive's longest side
_EPS = 1e-9
EMPTY = -1e9  # the radius of a node that holds nothing: every test passes it by


@dataclass(frozen=True)
class SphereTree:
    """Nodes in breadth-first order (node 0 the root), a node's children contiguous."""

    centre: FloatArray  # (N, 3), shape frame
    radius: FloatArray  # (N,)
    first_child: IntArray  # (N,) −1 for a leaf
    children: IntArray  # (N,)
    reach: FloatArray  # (N,) leaves: how far the centre may be from the shape (0 inside)


_TREES: weakref.WeakKeyDictionary[Shape, dict[float, SphereTree]] = weakref.WeakKeyDictionary()


def sphere_tree(shape: Shape, leaf: float = LEAF_M) -> SphereTree:
    """The shape's tree (module docstring), built once per shape object (model variants share
    their elements' shapes)."""
    trees = _TREES.setdefault(shape, {})
    tree = trees.get(leaf)
    if tree is None:
        tree = trees[leaf] = _build(shape, leaf)
    return tree


def _build(shape: Shape, leaf: float) -> SphereTree:
    """The tree from the disk cache (`geometry/disk_cache.py`), else built and stored."""
    content: list[object] = [shape.kind.value, np.asarray(shape.size, dtype=float), leaf]
    if shape.kind is ShapeKind.MESH:
        content += [np.asarray(shape.vertices, dtype=float), np.asarray(shape.faces, np.int64)]
    arrays = cached_arrays("sphere-trees", digest(content), lambda: _arrays(_tree(shape, leaf)))
    return SphereTree(
        centre=arrays["centre"],
        radius=arrays["radius"],
        first_child=arrays["first_child"].astype(np.int64),
        children=arrays["children"].astype(np.int64),
        reach=arrays["reach"],
    )


def _arrays(tree: SphereTree) -> dict[str, np.ndarray]:
    return {
        "centre": tree.centre,
        "radius": tree.radius,
        "first_child": tree.first_child,
        "children": tree.children,
        "reach": tree.reach,
    }


def _tree(shape: Shape, leaf: float) -> SphereTree:
    if shape.kind is ShapeKind.MESH:
        assert shape.vertices is not None and shape.faces is not None
        return _mesh_tree(np.asarray(shape.vertices, float), np.asarray(shape.faces), leaf)
    cells = min(_PRIMITIVE_CELLS, max(3, math.ceil(2.0 * float(shape.half_extents().max()) / leaf)))
    centres, radii = sphere_cover(shape, cells)
    count = len(radii)
    return SphereTree(
        centre=np.vstack([np.zeros((1, 3)), centres]),
        radius=np.r_[shape.bounding_radius() + _EPS, radii],
        first_child=np.r_[1, np.full(count, -1)].astype(np.int64),
        children=np.r_[count, np.zeros(count)].astype(np.int64),
        reach=np.zeros(count + 1),
    )


def _tighten(centre: FloatArray, radius: FloatArray, first: IntArray, count: IntArray) -> None:
    """Move and shrink each inner ball, children first, to one about the centre of its
    children's balls' bounding box that holds those balls (what the leaves cover lies in them),
    when that is smaller than its cube's ball."""
    for k in range(len(radius) - 1, -1, -1):
        if first[k] < 0:
            continue
        kids = np.arange(first[k], first[k] + count[k])
        kids = kids[radius[kids] > EMPTY]
        if len(kids) == 0:
            radius[k] = EMPTY
            continue
        lo = (centre[kids] - radius[kids, None]).min(axis=0)
        hi = (centre[kids] + radius[kids, None]).max(axis=0)
        middle = (lo + hi) / 2.0
        reach = float((np.linalg.norm(centre[kids] - middle, axis=1) + radius[kids]).max())
        if reach < radius[k]:
            centre[k], radius[k] = middle, reach + _EPS


_OCTANTS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)


def _mesh_tree(vertices: FloatArray, faces: IntArray, leaf: float) -> SphereTree:
    """The octree, level by level: a child cube is kept when the exact distance from its centre
    to the nearest triangle (trimesh) is at most its half diagonal, which is necessary for a
    triangle to meet it."""
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    extent = float((hi - lo).max()) + _EPS
    half = leaf / 2.0 * 2.0 ** max(math.ceil(math.log2(extent / leaf)), 0)  # leaves of side `leaf`
    centres, halves = [((lo + hi) / 2.0)[None]], [half]
    _, root_distance, _ = trimesh.proximity.closest_point(mesh, centres[0])
    reaches = [np.asarray(root_distance, dtype=float) + 1e-6]
    firsts: list[IntArray] = []
    counts: list[IntArray] = []
    total = 1
    while 2.0 * half > leaf:
        parents = centres[-1]
        half /= 2.0
        children = (parents[:, None, :] + _OCTANTS[None] * half).reshape(-1, 3)
        _, distance, _ = trimesh.proximity.closest_point(mesh, children)
        keep = np.asarray(distance) <= half * math.sqrt(3.0) * (1.0 + 1e-9) + _EPS
        per_parent = keep.reshape(-1, 8).sum(axis=1)
        firsts.append(total + np.r_[0, np.cumsum(per_parent)[:-1]])
        counts.append(per_parent)
        centres.append(children[keep])
        halves.append(half)
        reaches.append(np.asarray(distance)[keep] + 1e-6)
        total += int(keep.sum())
    firsts.append(np.full(len(centres[-1]), -1))
    counts.append(np.zeros(len(centres[-1]), dtype=np.int64))
    first = np.concatenate(firsts).astype(np.int64)
    count = np.concatenate(counts).astype(np.int64)
    radius = np.concatenate(
        [np.full(len(c), h * math.sqrt(3.0) + _EPS) for c, h in zip(centres, halves, strict=True)]
    )
    # A cube above the leaves with no child kept holds no point of the mesh (a point in it lies
    # in one of its children, whose centre is then near enough to be kept): an empty ball.
    empty = (count == 0) & (np.arange(len(first)) < len(first) - len(centres[-1]))
    radius[empty] = EMPTY
    first[count == 0] = -1
    centre = np.vstack(centres)
    _tighten(centre, radius, first, count)
    return SphereTree(
        centre=centre,
        radius=radius,
        first_child=first,
        children=count,
        reach=np.concatenate(reaches),
    )
