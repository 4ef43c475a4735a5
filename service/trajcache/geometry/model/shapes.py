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

    def hull_is_tight(self) -> bool:
        """True for a primitive, and for a closed mesh within 0.1 % of its convex hull's
        volume: measuring it as its hull then loses next to nothing (micrometres on the
        Panda's links), so its triangles need not be measured. Either answer is safe: the
        hull's distance never exceeds the mesh's."""
        if self.kind is not ShapeKind.MESH:
            return True
        mesh = trimesh.Trimesh(self.vertices, self.faces, process=False)
        if not mesh.is_watertight:
            return False
        try:
            return bool(abs(mesh.volume) >= (1.0 - 1e-3) * mesh.convex_hull.volume)
        except (QhullError, ValueError):
            return False

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
