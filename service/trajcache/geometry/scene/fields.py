"""The checked fields of a scene document: numbers, quaternions, poses, shapes, object ids, env.

Shared by the native payload (`payload.py`) and the MoveIt parser (`moveit.py`); every error
names where in the document it is. Quaternions are (x, y, z, w); one whose norm lies in
[0.9, 1.1] is normalized, any other is rejected, so that a sloppily rounded quaternion works but
a wrong one does not pass silently.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind, pose_matrix

MAX_MESH_VERTICES = 200_000
QUATERNION_NORM_TOLERANCE = 0.1
_SIZE_LENGTHS = {ShapeKind.BOX: 3, ShapeKind.SPHERE: 1, ShapeKind.CYLINDER: 2, ShapeKind.CAPSULE: 2}


def finite_number(value: Any, where: str) -> float:
    """A finite float, or SceneError naming `where`."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SceneError(f"{where} must be a number, got {value!r:.40}")
    try:
        out = float(value)
    except OverflowError:  # a huge JSON integer
        out = math.inf
    if not math.isfinite(out):
        raise SceneError(f"{where} must be finite, got {out}")
    return out


def number_list(value: Any, length: int, where: str, names: str = "") -> list[float]:
    """`length` finite numbers from a list, or from a mapping keyed by the letters of `names`."""
    if names and isinstance(value, Mapping):
        return [finite_number(value.get(k, 0.0), f"{where}.{k}") for k in names]
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise SceneError(f"{where} must be a list of {length} numbers")
    if len(value) != length:
        raise SceneError(f"{where} must have {length} values, got {len(value)}")
    return [finite_number(v, f"{where}[{i}]") for i, v in enumerate(value)]


def unit_quaternion(value: Any, where: str, *, zero_is_identity: bool = False) -> FloatArray:
    """A normalized (x, y, z, w) quaternion; norms outside [0.9, 1.1] are rejected."""
    q = np.array(number_list(value, 4, where, "xyzw"))
    norm = float(np.linalg.norm(q))
    if norm == 0.0:
        if zero_is_identity:
            return np.array([0.0, 0.0, 0.0, 1.0])
        raise SceneError(f"{where} is a zero quaternion")
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise SceneError(f"{where} is not a unit quaternion (norm {norm:.4g})")
    return q / norm


def parse_pose(value: Any, where: str, *, zero_is_identity: bool = False) -> FloatArray:
    """4×4 pose from `{"position": [x,y,z], "orientation": [x,y,z,w]}` (lists or x/y/z/w maps)."""
    if value is None:
        return np.eye(4)
    if not isinstance(value, Mapping):
        raise SceneError(f"{where} must be a mapping with position and orientation")
    position = number_list(value.get("position", [0.0, 0.0, 0.0]), 3, f"{where}.position", "xyz")
    orientation = value.get("orientation")
    if orientation is None:
        return pose_matrix(position, [0.0, 0.0, 0.0, 1.0])
    q = unit_quaternion(orientation, f"{where}.orientation", zero_is_identity=zero_is_identity)
    return pose_matrix(position, q)


def make_shape(
    oid: str, kind: ShapeKind, size: Sequence[float], vertices: Any = None, faces: Any = None
) -> Shape:
    """Validated Shape for object `oid`; every error names the object and the field."""
    where = f"object {oid!r}"
    if kind is not ShapeKind.MESH:
        dims = number_list(size, _SIZE_LENGTHS[kind], f"{where}: size")
        for i, v in enumerate(dims):
            if v <= 0.0:
                raise SceneError(f"{where}: size[{i}] must be positive, got {v}")
        return Shape(kind, tuple(dims))
    try:
        verts = np.array(vertices, dtype=float)
        tris = np.array(faces, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{where}: mesh vertices and faces must be numeric arrays") from exc
    if verts.ndim != 2 or verts.shape[1] != 3 or not 3 <= len(verts) <= MAX_MESH_VERTICES:
        raise SceneError(f"{where}: vertices must be 3..{MAX_MESH_VERTICES} [x, y, z] rows")
    if not np.all(np.isfinite(verts)):
        raise SceneError(f"{where}: vertices must be finite")
    if tris.ndim != 2 or tris.shape[1] != 3 or len(tris) == 0 or len(tris) > 2 * MAX_MESH_VERTICES:
        raise SceneError(f"{where}: faces must be a non-empty list of [i, j, k] triangles")
    if not np.all(np.isfinite(tris)) or np.any(tris != np.round(tris)):
        raise SceneError(f"{where}: faces must hold integer vertex indices")
    if tris.min() < 0 or tris.max() >= len(verts):
        raise SceneError(f"{where}: faces index a vertex outside 0..{len(verts) - 1}")
    return Shape(kind, (), vertices=verts, faces=tris.astype(np.int64))


def object_id(value: Any, where: str) -> str:
    """An object id: a non-empty string of at most 200 characters."""
    if not isinstance(value, str) or not value.strip() or len(value) > 200:
        raise SceneError(f"{where}: id must be a non-empty string of at most 200 characters")
    return value


def parse_env(value: Any) -> dict[str, float]:
    """Environment values: string keys, finite numbers."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise SceneError("env must be a mapping of names to numbers")
    env: dict[str, float] = {}
    for key, v in value.items():
        if not isinstance(key, str) or not key:
            raise SceneError(f"env key {key!r} must be a non-empty string")
        env[key] = finite_number(v, f"env[{key!r}]")
    return env
