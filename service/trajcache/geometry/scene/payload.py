"""The native scene payload: parsing, serialization and patching.

`{"objects": [{"id", "type", "size", "pose": {"position", "orientation"}}], "env": {...},
"allowed_collisions": [[name, name]], "attached_objects": [{"link", "object": {native object,
posed in the link frame}, "touch_links": [links it may touch]}]}` (`scene.py` says what the
last two mean); `parse.py` also accepts a MoveIt `PlanningScene` (`moveit.py`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from trajcache.core.suggest import unknown_message
from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.shapes import ShapeKind
from trajcache.geometry.scene.fields import (
    finite_number,
    make_shape,
    object_id,
    parse_pose,
)
from trajcache.geometry.scene.scene import (
    MAX_OBJECTS,
    AttachedObject,
    Scene,
    SceneObject,
    make_scene,
    matrix_to_quaternion,
)

_OBJECT_ORDER = ("id", "type", "size", "pose", "vertices", "faces")
_OBJECT_KEYS = frozenset(_OBJECT_ORDER)
# What a misplaced or misnamed key was meant to be: a pose's parts belong in `pose`.
_OBJECT_SYNONYMS = {"position": "pose", "orientation": "pose", "dimensions": "size"}
_TYPE_SYNONYMS = {"cube": "box", "cuboid": "box", "ball": "sphere", "tube": "cylinder"}
_SCENE_KEYS = frozenset({"objects", "env", "allowed_collisions", "attached_objects"})
_ATTACHED_KEYS = frozenset({"link", "object", "touch_links"})
_IGNORED_TOP_KEYS = frozenset({"name", "version", "hash"})


def parse_object(raw: Any, where: str) -> SceneObject:
    """One object in native form."""
    if not isinstance(raw, Mapping):
        raise SceneError(f"{where} must be a mapping")
    oid = object_id(raw.get("id"), where)
    unknown = sorted(str(k) for k in raw if k not in _OBJECT_KEYS)
    if unknown:
        message = unknown_message("field", unknown, _OBJECT_ORDER, synonyms=_OBJECT_SYNONYMS)
        raise SceneError(f"object {oid!r}: {message}")
    kind_name = raw.get("type")
    try:
        kind = ShapeKind(str(kind_name).lower())
    except ValueError:
        kinds = [k.value for k in ShapeKind]
        message = unknown_message("type", [str(kind_name)], kinds, synonyms=_TYPE_SYNONYMS)
        raise SceneError(f"object {oid!r}: {message}") from None
    if kind is ShapeKind.MESH and raw.get("size"):
        raise SceneError(f"object {oid!r}: a mesh takes no size (scale its vertices)")
    shape = make_shape(oid, kind, raw.get("size", ()), raw.get("vertices"), raw.get("faces"))
    return SceneObject(oid, shape, parse_pose(raw.get("pose"), f"object {oid!r}: pose"))


def parse_native_scene(payload: Mapping[str, Any], env: dict[str, float]) -> Scene:
    """Parse a native scene payload, its `env` already parsed (`parse.parse_scene` takes either
    format)."""
    unknown = sorted(str(k) for k in payload if k not in _SCENE_KEYS | _IGNORED_TOP_KEYS)
    if unknown:
        raise SceneError(unknown_message("scene field", unknown, sorted(_SCENE_KEYS)))
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
            raise SceneError(
                f"{where}: {unknown_message('field', unknown, sorted(_ATTACHED_KEYS))}"
            )
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
        raise SceneError(unknown_message("patch field", unknown, ["upsert", "remove", "env"]))
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
        object_id(oid, f"remove[{i}]")
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
