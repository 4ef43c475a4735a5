"""Coal geometry for bench/dense_mesh.py's check: meshes read as written, scene objects as
primitives.

Independent of the service: an OBJ file's triangles are read here (`obj_triangles`), not through
assimp, and each scene object of the native payload becomes a coal primitive.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def obj_triangles(path: Path) -> tuple[FloatArray, NDArray[np.int64]]:
    """The vertices and triangles of a Wavefront OBJ file as written: `v` lines, and `f` lines
    (1-based or negative indices, polygons fanned into triangles). Read here rather than by
    assimp, whose import of such a file can hold triangles the file does not: on the MBM
    Panda's link6.obj (24 vertices no face uses) one lay 8 mm off the mesh, and coal then saw
    contacts that were not there."""
    vertices: list[list[float]] = []
    faces: list[list[int]] = []
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            vertices.append([float(x) for x in parts[1:4]])
        elif parts[0] == "f":
            index = [int(item.split("/")[0]) for item in parts[1:]]
            index = [i - 1 if i > 0 else len(vertices) + i for i in index]
            faces += [[index[0], index[k], index[k + 1]] for k in range(1, len(index) - 1)]
    return np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64)


def obj_meshes_as_written(geoms: pin.GeometryModel) -> None:
    """Replace each OBJ collision mesh's coal model by one of its triangles as written
    (`obj_triangles`), scaled as the URDF says."""
    for obj in geoms.geometryObjects:
        path = Path(obj.meshPath) if obj.meshPath else None
        if path is None or path.suffix.lower() != ".obj" or not path.is_file():
            continue
        vertices, faces = obj_triangles(path)
        vertices = vertices * np.asarray(obj.meshScale, dtype=float)
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(faces), len(vertices))
        bvh.addVertices(vertices)
        bvh.addTriangles(faces)
        bvh.endModel()
        obj.geometry = bvh


def quaternion_placement(pose: Mapping[str, Any] | None) -> pin.SE3:
    """The placement of a payload pose (position, orientation x, y, z, w); identity if absent."""
    pose = pose or {}
    x, y, z, w = pose.get("orientation") or (0.0, 0.0, 0.0, 1.0)
    rotation = pin.Quaternion(float(w), float(x), float(y), float(z)).normalized().matrix()
    return pin.SE3(rotation, np.asarray(pose.get("position") or (0.0, 0.0, 0.0), dtype=float))


def scene_geometry(obj: Mapping[str, Any]) -> coal.CollisionGeometry:
    """A coal primitive for one scene object of the native payload."""
    kind, size = obj["type"], [float(v) for v in obj["size"]]
    if kind == "box":
        return coal.Box(*size)  # full side lengths
    if kind == "sphere":
        return coal.Sphere(size[0])
    if kind == "cylinder":
        return coal.Cylinder(size[0], size[1])
    if kind == "capsule":
        return coal.Capsule(size[0], size[1])
    raise ValueError(f"scene object {obj['id']!r}: type {kind!r} is not supported here")
