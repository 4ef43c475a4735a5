"""Scenes: collision objects in the world frame plus named environment values.

Native payload: `{"objects": [{"id", "type", "size", "pose": {"position", "orientation"}}],
"env": {...}}`; `parse.py` also accepts a MoveIt `PlanningScene` (`moveit.py`).

A scene may also carry what the robot team says about contact in it, which is part of its hash:
- `allowed_collisions`: pairs of names whose contact is allowed, as a MoveIt allowed collision
  matrix gives them: a link and an object (a part the hand holds, a table the base stands on),
  or two links (adjusting the model's matrix for this scene). An object id also covers the
  parts `id#1`, `id#2` … of a multi-shape object.
- `attached_objects`: objects that travel with a link (`{"link", "object": {native object, posed
  in the link frame}, "touch_links": [links it may touch]}`); they are checked against the scene
  and against the robot's other links.
Quaternions are (x, y, z, w); one whose norm lies in [0.9, 1.1] is normalized, any other is
rejected, so that a sloppily rounded quaternion works but a wrong one does not pass silently.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind, pose_matrix

MAX_OBJECTS = 10_000
MAX_MESH_VERTICES = 200_000
QUATERNION_NORM_TOLERANCE = 0.1
_SIZE_LENGTHS = {ShapeKind.BOX: 3, ShapeKind.SPHERE: 1, ShapeKind.CYLINDER: 2, ShapeKind.CAPSULE: 2}
_OBJECT_KEYS = frozenset({"id", "type", "size", "pose", "vertices", "faces"})
_SCENE_KEYS = frozenset({"objects", "env", "allowed_collisions", "attached_objects"})
_ATTACHED_KEYS = frozenset({"link", "object", "touch_links"})
MAX_ALLOWED_PAIRS = 10_000
_IGNORED_TOP_KEYS = frozenset({"name", "version", "hash"})


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One obstacle: an id unique in its scene, a shape and its world pose (4×4)."""

    id: str
    shape: Shape
    pose: FloatArray


@dataclass(frozen=True, eq=False)
class AttachedObject:
    """An object that travels with a robot link; its pose is in the link's frame."""

    link: str
    object: SceneObject
    touch_links: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class Scene:
    """An immutable scene; `hash` is a canonical content hash (objects order-independent).

    `allowed` holds name pairs (sorted) whose contact is allowed; `warnings` tells what of the
    uploaded document was not applied (not part of the hash).
    """

    objects: tuple[SceneObject, ...]
    env: dict[str, float] = field(default_factory=dict)
    hash: str = ""
    allowed: frozenset[tuple[str, str]] = frozenset()
    attached: tuple[AttachedObject, ...] = ()
    warnings: tuple[str, ...] = ()

    def allows(self, a: str, b: str) -> bool:
        """Whether contact between names `a` and `b` is allowed (object parts included)."""
        a, b = a.partition("#")[0], b.partition("#")[0]
        return (min(a, b), max(a, b)) in self.allowed


# --- validation helpers (shared with the MoveIt parser) ------------------------------------


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


def _object_id(value: Any, where: str) -> str:
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


def parse_object(raw: Any, where: str) -> SceneObject:
    """One object in native form."""
    if not isinstance(raw, Mapping):
        raise SceneError(f"{where} must be a mapping")
    oid = _object_id(raw.get("id"), where)
    unknown = sorted(str(k) for k in raw if k not in _OBJECT_KEYS)
    if unknown:
        raise SceneError(f"object {oid!r}: unknown field(s) {', '.join(unknown)}")
    kind_name = raw.get("type")
    try:
        kind = ShapeKind(str(kind_name).lower())
    except ValueError:
        raise SceneError(f"object {oid!r}: unknown type {kind_name!r}") from None
    if kind is ShapeKind.MESH and raw.get("size"):
        raise SceneError(f"object {oid!r}: a mesh takes no size (scale its vertices)")
    shape = make_shape(oid, kind, raw.get("size", ()), raw.get("vertices"), raw.get("faces"))
    return SceneObject(oid, shape, parse_pose(raw.get("pose"), f"object {oid!r}: pose"))


# --- hashing and construction ---------------------------------------------------------------


def matrix_to_quaternion(pose: FloatArray) -> FloatArray:
    """(x, y, z, w) unit quaternion of a 4×4 (or 3×3) rotation, with w ≥ 0."""
    m = np.asarray(pose, dtype=float)[:3, :3]
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
    out = np.array(q) / np.linalg.norm(q)
    return -out if out[3] < 0.0 else out


def _rounded(values: Iterable[float]) -> list[float]:
    return [round(float(v), 9) + 0.0 for v in values]  # + 0.0 turns -0.0 into 0.0


def _canonical_quaternion(obj: SceneObject) -> list[float]:
    if obj.shape.kind is ShapeKind.SPHERE:  # a sphere's orientation does not change its geometry
        return [0.0, 0.0, 0.0, 1.0]
    q = _rounded(matrix_to_quaternion(obj.pose))
    lead = next((v for v in (q[3], q[0], q[1], q[2]) if v != 0.0), 1.0)
    return [v * -1.0 + 0.0 for v in q] if lead < 0.0 else q


def _canonical_object(obj: SceneObject) -> dict[str, Any]:
    return {
        "id": obj.id,
        "shape": obj.shape.canonical(),
        "position": _rounded(obj.pose[:3, 3]),
        "orientation": _canonical_quaternion(obj),
    }


def scene_hash(
    objects: Iterable[SceneObject],
    env: Mapping[str, float],
    allowed: Iterable[tuple[str, str]] = (),
    attached: Iterable[AttachedObject] = (),
) -> str:
    """sha256 of the canonical JSON of the objects (sorted by id), the env (sorted by key) and,
    when there are any, the allowed pairs and the attached objects."""
    entries = [_canonical_object(obj) for obj in sorted(objects, key=lambda o: o.id)]
    doc: dict[str, Any] = {
        "objects": entries,
        "env": [[k, _rounded([env[k]])[0]] for k in sorted(env)],
    }
    if pairs := sorted(allowed):
        doc["allowed"] = [list(p) for p in pairs]
    if held := sorted(attached, key=lambda a: a.object.id):
        doc["attached"] = [
            {**_canonical_object(a.object), "link": a.link, "touch": sorted(a.touch_links)}
            for a in held
        ]
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def make_scene(
    objects: Iterable[SceneObject],
    env: Mapping[str, float] | None = None,
    *,
    allowed: Iterable[tuple[str, str]] = (),
    attached: Iterable[AttachedObject] = (),
    warnings: Iterable[str] = (),
) -> Scene:
    """A Scene with its hash filled in; duplicate ids and non-finite env values are rejected."""
    objs = tuple(objects)
    held = tuple(attached)
    pairs = frozenset((min(a, b), max(a, b)) for a, b in allowed)
    if len(pairs) > MAX_ALLOWED_PAIRS:
        raise SceneError(f"a scene may allow at most {MAX_ALLOWED_PAIRS} pairs")
    if len(objs) > MAX_OBJECTS:
        raise SceneError(f"a scene may hold at most {MAX_OBJECTS} objects, got {len(objs)}")
    seen: set[str] = set()
    for obj in (*objs, *(a.object for a in held)):
        if obj.id in seen:
            raise SceneError(f"duplicate object id {obj.id!r}")
        seen.add(obj.id)
        if not np.all(np.isfinite(obj.pose)):
            raise SceneError(f"object {obj.id!r}: pose must be finite")
    clean_env = parse_env(dict(env or {}))
    return Scene(
        objs,
        clean_env,
        scene_hash(objs, clean_env, pairs, held),
        allowed=pairs,
        attached=held,
        warnings=tuple(warnings),
    )


# --- public parsing, serialization and patching ---------------------------------------------


def parse_native_scene(payload: Mapping[str, Any], env: dict[str, float]) -> Scene:
    """Parse a native scene payload, its `env` already parsed (`parse.parse_scene` takes either
    format)."""
    unknown = sorted(str(k) for k in payload if k not in _SCENE_KEYS | _IGNORED_TOP_KEYS)
    if unknown:
        raise SceneError(f"unknown scene field(s) {', '.join(unknown)}")
    raw_objects = payload.get("objects", [])
    if not isinstance(raw_objects, Sequence) or isinstance(raw_objects, str):
        raise SceneError("objects must be a list")
    if len(raw_objects) > MAX_OBJECTS:
        raise SceneError(f"a scene may hold at most {MAX_OBJECTS} objects")
    return make_scene(
        [parse_object(o, f"objects[{i}]") for i, o in enumerate(raw_objects)],
        env,
        allowed=parse_allowed(payload.get("allowed_collisions")),
        attached=parse_attached(payload.get("attached_objects")),
    )


def _names(value: Any, where: str) -> list[str]:
    if value is None:
        return []
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise SceneError(f"{where} must be a list of names")
    for i, name in enumerate(value):
        if not isinstance(name, str) or not name or len(name) > 200:
            raise SceneError(f"{where}[{i}] must be a non-empty name of at most 200 characters")
    return list(value)


def parse_allowed(value: Any) -> list[tuple[str, str]]:
    """`allowed_collisions`: a list of [name, name] pairs."""
    if value is None:
        return []
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise SceneError("allowed_collisions must be a list of [name, name] pairs")
    pairs = []
    for i, raw in enumerate(value):
        names = _names(raw, f"allowed_collisions[{i}]")
        if len(names) != 2 or names[0] == names[1]:
            raise SceneError(f"allowed_collisions[{i}] must be two different names")
        pairs.append((names[0], names[1]))
    return pairs


def parse_attached(value: Any) -> list[AttachedObject]:
    """`attached_objects`: objects posed in the frame of the link that carries them."""
    if value is None:
        return []
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise SceneError("attached_objects must be a list")
    out = []
    for i, raw in enumerate(value):
        where = f"attached_objects[{i}]"
        if not isinstance(raw, Mapping):
            raise SceneError(f"{where} must be a mapping")
        unknown = sorted(str(k) for k in raw if k not in _ATTACHED_KEYS)
        if unknown:
            raise SceneError(f"{where}: unknown field(s) {', '.join(unknown)}")
        link = raw.get("link")
        if not isinstance(link, str) or not link:
            raise SceneError(f"{where}: link must name a robot link")
        obj = parse_object(raw.get("object"), f"{where}.object")
        touch = _names(raw.get("touch_links"), f"{where}.touch_links")
        out.append(AttachedObject(link, obj, tuple(touch)))
    return out


def object_to_payload(obj: SceneObject) -> dict[str, Any]:
    """One object in native form."""
    out: dict[str, Any] = {"id": obj.id, "type": obj.shape.kind.value}
    if obj.shape.kind is ShapeKind.MESH:
        assert obj.shape.vertices is not None and obj.shape.faces is not None
        out["vertices"] = obj.shape.vertices.tolist()
        out["faces"] = obj.shape.faces.tolist()
    else:
        out["size"] = [float(v) for v in obj.shape.size]
    out["pose"] = {
        "position": [float(v) for v in obj.pose[:3, 3]],
        "orientation": [float(v) for v in matrix_to_quaternion(obj.pose)],
    }
    return out


def scene_to_payload(scene: Scene) -> dict[str, Any]:
    """The scene in native form (`parse_scene` of it gives the same hash)."""
    out: dict[str, Any] = {
        "objects": [object_to_payload(o) for o in scene.objects],
        "env": dict(scene.env),
    }
    if scene.allowed:
        out["allowed_collisions"] = [list(pair) for pair in sorted(scene.allowed)]
    if scene.attached:
        out["attached_objects"] = [
            {
                "link": a.link,
                "object": object_to_payload(a.object),
                "touch_links": list(a.touch_links),
            }
            for a in scene.attached
        ]
    return out


def apply_patch(scene: Scene, patch: Mapping[str, Any]) -> Scene:
    """Apply `{"upsert": [objects], "remove": [ids], "env": {key: value | null}}`."""
    if not isinstance(patch, Mapping):
        raise SceneError("a scene patch must be a mapping")
    unknown = sorted(str(k) for k in patch if k not in {"upsert", "remove", "env"})
    if unknown:
        raise SceneError(f"unknown patch field(s) {', '.join(unknown)}")
    upserts = patch.get("upsert") or []
    removes = patch.get("remove") or []
    env_patch = patch.get("env") or {}
    if not isinstance(upserts, Sequence) or isinstance(upserts, str):
        raise SceneError("upsert must be a list of objects")
    if not isinstance(removes, Sequence) or isinstance(removes, str):
        raise SceneError("remove must be a list of object ids")
    if not isinstance(env_patch, Mapping):
        raise SceneError("env must be a mapping of names to numbers or null")
    objects = {o.id: o for o in scene.objects}
    for i, oid in enumerate(removes):
        _object_id(oid, f"remove[{i}]")
        if oid not in objects:
            raise SceneError(f"cannot remove object {oid!r}: not in the scene")
        del objects[oid]
    new_objects = [parse_object(o, f"upsert[{i}]") for i, o in enumerate(upserts)]
    upserted: set[str] = set()
    for obj in new_objects:
        if obj.id in upserted:
            raise SceneError(f"duplicate object id {obj.id!r} in upsert")
        if obj.id in removes:
            raise SceneError(f"object {obj.id!r} is both removed and upserted")
        upserted.add(obj.id)
        objects[obj.id] = obj  # dicts keep insertion order: replaced ids stay in place
    env = dict(scene.env)
    for key, value in env_patch.items():
        if not isinstance(key, str) or not key:
            raise SceneError(f"env key {key!r} must be a non-empty string")
        if value is None:
            env.pop(key, None)
        else:
            env[key] = finite_number(value, f"env[{key!r}]")
    return make_scene(objects.values(), env, allowed=scene.allowed, attached=scene.attached)
