"""Collision shapes shared by robot links and scene objects, and their FCL counterparts."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import coal
import fcl
import numpy as np
import trimesh
from numpy.typing import NDArray
from scipy.spatial import QhullError

from trajcache.geometry.disk_cache import cached_arrays, digest
from trajcache.geometry.errors import SceneError

FloatArray = NDArray[np.float64]


class ShapeKind(str, Enum):
    """Primitive kinds understood by the collision layer."""

    BOX = "box"
    SPHERE = "sphere"
    CYLINDER = "cylinder"
    CAPSULE = "capsule"
    MESH = "mesh"


@dataclass(frozen=True, eq=False)
class Shape:
    """One collision primitive in its own frame (cylinders and capsules along local z).

    `size` is (x, y, z) full extents for a box, (radius,) for a sphere and (radius, length) for a
    cylinder or capsule (length excludes the capsule's hemispherical caps). A mesh keeps its
    scaled vertices (V, 3) and triangle indices (F, 3).
    """

    kind: ShapeKind
    size: tuple[float, ...] = ()
    vertices: FloatArray | None = field(default=None, repr=False)
    faces: NDArray[np.int64] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        expected = {
            ShapeKind.BOX: 3,
            ShapeKind.SPHERE: 1,
            ShapeKind.CYLINDER: 2,
            ShapeKind.CAPSULE: 2,
            ShapeKind.MESH: 0,
        }[self.kind]
        if len(self.size) != expected:
            raise SceneError(
                f"{self.kind.value} needs {expected} size values, got {len(self.size)}"
            )
        if not all(np.isfinite(v) and v > 0 for v in self.size):
            raise SceneError(f"{self.kind.value} sizes must be finite and positive: {self.size}")
        if self.kind is ShapeKind.MESH:
            if self.vertices is None or self.faces is None or len(self.faces) == 0:
                raise SceneError("mesh needs vertices and at least one triangle")
            if not np.all(np.isfinite(self.vertices)):
                raise SceneError("mesh vertices must be finite")

    def bounding_radius(self) -> float:
        """Radius of the smallest origin-centred sphere that contains the shape."""
        if self.kind is ShapeKind.BOX:
            return float(np.linalg.norm(self.size) / 2.0)
        if self.kind is ShapeKind.SPHERE:
            return self.size[0]
        if self.kind is ShapeKind.CYLINDER:
            return float(np.hypot(self.size[0], self.size[1] / 2.0))
        if self.kind is ShapeKind.CAPSULE:
            return self.size[0] + self.size[1] / 2.0
        assert self.vertices is not None
        return float(np.max(np.linalg.norm(self.vertices, axis=1)))

    def half_extents(self) -> FloatArray:
        """Half extents of the shape's axis-aligned box in its own frame."""
        if self.kind is ShapeKind.BOX:
            return np.asarray(self.size, dtype=float) / 2.0
        if self.kind is ShapeKind.SPHERE:
            return np.full(3, self.size[0])
        if self.kind in (ShapeKind.CYLINDER, ShapeKind.CAPSULE):
            r, length = self.size
            cap = r if self.kind is ShapeKind.CAPSULE else 0.0
            return np.array([r, r, length / 2.0 + cap])
        assert self.vertices is not None
        return np.max(np.abs(self.vertices), axis=0)

    def to_fcl(self) -> fcl.CollisionGeometry:
        """Build the FCL geometry for this shape."""
        if self.kind is ShapeKind.BOX:
            return fcl.Box(*self.size)
        if self.kind is ShapeKind.SPHERE:
            return fcl.Sphere(self.size[0])
        if self.kind is ShapeKind.CYLINDER:
            return fcl.Cylinder(self.size[0], self.size[1])
        if self.kind is ShapeKind.CAPSULE:
            return fcl.Capsule(self.size[0], self.size[1])
        assert self.vertices is not None and self.faces is not None
        bvh = fcl.BVHModel()
        bvh.beginModel(len(self.vertices), len(self.faces))
        bvh.addSubModel(self.vertices, self.faces)
        bvh.endModel()
        return bvh

    def to_coal(self) -> coal.CollisionGeometry:
        """Build the coal geometry for this shape (exact distances: `narrow.Narrow.exact`).

        coal takes the same conventions as FCL: full box extents, cylinders and capsules along
        local z with the length between their end faces or cap centres.
        """
        if self.kind is ShapeKind.BOX:
            return coal.Box(*self.size)
        if self.kind is ShapeKind.SPHERE:
            return coal.Sphere(self.size[0])
        if self.kind is ShapeKind.CYLINDER:
            return coal.Cylinder(self.size[0], self.size[1])
        if self.kind is ShapeKind.CAPSULE:
            return coal.Capsule(self.size[0], self.size[1])
        assert self.vertices is not None and self.faces is not None
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(self.faces), len(self.vertices))
        bvh.addVertices(np.asarray(self.vertices, dtype=float))
        bvh.addTriangles(np.asarray(self.faces, dtype=np.int64))
        bvh.endModel()
        return bvh

    def to_coal_hull(self, exact: coal.CollisionGeometry) -> coal.CollisionGeometry:
        """The convex hull of a mesh's coal geometry `exact` (from `to_coal`), whose distance
        is a lower bound of the mesh's and several times cheaper; `exact` itself for a
        primitive, or for a mesh without a 3-D hull (flat, or under four points)."""
        if self.kind is not ShapeKind.MESH:
            return exact
        try:
            exact.buildConvexHull(True, "Qt")
        except ValueError:
            return exact
        return exact.convex

    def hull_gap(self) -> float:
        """How far the shape's convex hull strays from the shape: 0 for a primitive; for a mesh,
        the largest distance from a point of its hull's surface to its triangles, sampled (the
        hull's vertices and `GAP_SAMPLES` points spread over its faces), or inf for a mesh with
        no 3-D hull (flat). Kept on disk by the mesh's content (`disk_cache.py`).

        Where the hull's distance to another body is d, the triangles' is at most d + gap (the
        hull's nearest point is within gap of a triangle), so the triangles need measuring only
        where d + gap exceeds what is needed (`narrow.py`). A sampled gap can fall short of the
        largest; that only skips a measurement that might have proved more: the hull's distance
        is a lower bound either way.
        """
        if self.kind is not ShapeKind.MESH:
            return 0.0
        assert self.vertices is not None and self.faces is not None
        vertices, faces = np.asarray(self.vertices, float), np.asarray(self.faces, np.int64)
        key = digest([vertices, faces, GAP_SAMPLES])
        return float(cached_arrays("hull-gaps", key, lambda: _hull_gap(vertices, faces))["gap"])

    def canonical(self) -> dict[str, object]:
        """A JSON-ready description used for content hashing."""
        out: dict[str, object] = {"kind": self.kind.value, "size": [round(v, 9) for v in self.size]}
        if self.kind is ShapeKind.MESH:
            assert self.vertices is not None and self.faces is not None
            out["vertices"] = np.round(self.vertices, 9).tolist()
            out["faces"] = self.faces.tolist()
        return out


def pose_matrix(xyz: FloatArray | list[float], quat_xyzw: FloatArray | list[float]) -> FloatArray:
    """4×4 homogeneous transform from a translation and a unit quaternion (x, y, z, w)."""
    x, y, z, w = (float(v) for v in quat_xyzw)
    t = np.eye(4)
    t[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    t[:3, 3] = np.asarray(xyz, dtype=float)
    return t


GAP_SAMPLES = 2000  # points of a mesh's hull surface whose distance to its triangles is measured


def _hull_gap(vertices: FloatArray, faces: NDArray[np.int64]) -> dict[str, np.ndarray]:
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    try:
        hull = mesh.convex_hull
    except (QhullError, ValueError):
        return {"gap": np.array(np.inf)}
    if len(hull.faces) < 4 or hull.volume <= 0.0:
        return {"gap": np.array(np.inf)}
    points, _ = trimesh.sample.sample_surface_even(hull, GAP_SAMPLES, seed=0)
    points = np.vstack([points, hull.vertices])
    _, distance, _ = trimesh.proximity.closest_point(mesh, points)
    return {"gap": np.array(float(np.max(distance)))}
