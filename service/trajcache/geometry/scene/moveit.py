"""MoveIt `moveit_msgs/PlanningScene` ↔ scenes.

Accepted: the whole message (`world.collision_objects`), `{"world": {...}}` or
`{"collision_objects": [...]}`, as decoded from JSON/YAML (rosbridge-style dicts; points and
quaternions may also be plain lists). World objects must be in a world frame, or in a robot
frame the caller resolves (`frames.py`: the root link of a fixed base and links fixed to it). An
object with
several shapes becomes several scene objects `id`, `id#1`, `id#2` … (primitives first, then
meshes); the object pose composes with each shape pose. As in MoveIt itself, an all-zero
quaternion in a message means identity (a default-constructed pose).

Also honoured: `allowed_collision_matrix` (`entry_names` and `entry_values[i].enabled[j]`; true
allows contact between the two names: links, objects or attached objects) and
`robot_state.attached_collision_objects` (posed in the frame of their `link_name`, with their
`touch_links`). What is not applied comes back as the scene's warnings: the robot state's joint
values (each plan gives its own), default ACM entries, link padding and scale, fixed frame
transforms. A message with `is_diff: true` is changes to the robot's current scene
(`moveit_diff.py`); where there is no current scene to change, it is refused.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from trajcache.core.suggest import unknown_message
from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.shapes import FloatArray, ShapeKind
from trajcache.geometry.scene.fields import make_shape, number_list, parse_pose
from trajcache.geometry.scene.frames import NO_FRAMES, SceneFrames, object_frame
from trajcache.geometry.scene.scene import (
    MAX_OBJECTS,
    AttachedObject,
    Scene,
    SceneObject,
    make_scene,
    matrix_to_quaternion,
)

# shape_msgs/SolidPrimitive type constants
BOX, SPHERE, CYLINDER, CONE = 1, 2, 3, 4
_PRIMITIVE_NAMES = {"box": BOX, "sphere": SPHERE, "cylinder": CYLINDER, "cone": CONE}
# moveit_msgs/CollisionObject operation constants
ADD, REMOVE, APPEND, MOVE = 0, 1, 2, 3
_OPERATION_NAMES = {"add": ADD, "remove": REMOVE, "append": APPEND, "move": MOVE}


def _as_list(value: Any, where: str) -> Sequence[Any]:
    if value is None:
        return []
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise SceneError(f"{where} must be a list")
    return value


def collision_objects(payload: Mapping[str, Any]) -> Sequence[Any]:
    world = payload.get("world", payload)
    if not isinstance(world, Mapping):
        raise SceneError("world must be a mapping with collision_objects")
    octomap = world.get("octomap")
    if isinstance(octomap, Mapping):
        inner = octomap.get("octomap", octomap)
        if isinstance(inner, Mapping) and inner.get("data"):
            raise SceneError("octomaps are not supported; send collision objects")
    return _as_list(world.get("collision_objects"), "world.collision_objects")


def enum_operation(value: Any, where: str) -> int:
    """A CollisionObject operation, by number or name."""
    return _enum(value, _OPERATION_NAMES, where)


def _enum(value: Any, names: Mapping[str, int], where: str) -> int:
    if isinstance(value, str):
        code = names.get(value.strip().lower())
        if code is None:
            raise SceneError(f"{where}: {unknown_message('value', [value], list(names))}")
        return code
    if isinstance(value, bool) or not isinstance(value, int):
        raise SceneError(f"{where} must be an integer or a name, got {value!r:.40}")
    return value


def _primitive(raw: Any, oid: str, where: str) -> tuple[ShapeKind, list[float]]:
    if not isinstance(raw, Mapping):
        raise SceneError(f"object {oid!r}: {where} must be a mapping")
    code = _enum(raw.get("type"), _PRIMITIVE_NAMES, f"object {oid!r}: {where}.type")
    dims = raw.get("dimensions")
    if code == BOX:
        return ShapeKind.BOX, number_list(dims, 3, f"object {oid!r}: {where}.dimensions")
    if code == SPHERE:
        return ShapeKind.SPHERE, number_list(dims, 1, f"object {oid!r}: {where}.dimensions")
    if code == CYLINDER:  # SolidPrimitive cylinder is [height, radius]; Shape is (radius, length)
        height, radius = number_list(dims, 2, f"object {oid!r}: {where}.dimensions")
        return ShapeKind.CYLINDER, [radius, height]
    if code == CONE:
        raise SceneError(f"object {oid!r}: {where}.type cone is not supported")
    raise SceneError(f"object {oid!r}: {where}.type {code} is not a known primitive")


def _mesh(raw: Any, oid: str, where: str) -> tuple[Any, Any]:
    if not isinstance(raw, Mapping):
        raise SceneError(f"object {oid!r}: {where} must be a mapping")
    vertices = [
        number_list(v, 3, f"object {oid!r}: {where}.vertices[{i}]", "xyz")
        for i, v in enumerate(_as_list(raw.get("vertices"), f"object {oid!r}: {where}.vertices"))
    ]
    faces = []
    for i, tri in enumerate(_as_list(raw.get("triangles"), f"object {oid!r}: {where}.triangles")):
        indices = tri.get("vertex_indices") if isinstance(tri, Mapping) else tri
        faces.append(number_list(indices, 3, f"object {oid!r}: {where}.triangles[{i}]"))
    return vertices, faces


def _poses(obj: Mapping[str, Any], key: str, count: int, oid: str) -> list[FloatArray]:
    raw = _as_list(obj.get(key), f"object {oid!r}: {key}")
    if len(raw) != count:
        raise SceneError(f"object {oid!r}: {key} has {len(raw)} poses for {count} shapes")
    return [
        parse_pose(p, f"object {oid!r}: {key}[{i}]", zero_is_identity=True)
        for i, p in enumerate(raw)
    ]


def object_shapes(
    obj: Mapping[str, Any], oid: str, link: str | None = None, frames: SceneFrames = NO_FRAMES
) -> list[tuple[Any, FloatArray]]:
    """(Shape, pose) for every primitive then mesh of one CollisionObject: world poses (its
    frame resolved with `frames`), or poses in the frame of `link` for an attached object."""
    frame = object_frame(obj, oid, link, frames)
    if _as_list(obj.get("planes"), f"object {oid!r}: planes"):
        raise SceneError(f"object {oid!r}: planes are not supported")
    pose = parse_pose(obj.get("pose"), f"object {oid!r}: pose", zero_is_identity=True)
    base = frame @ pose
    out: list[tuple[Any, FloatArray]] = []
    primitives = _as_list(obj.get("primitives"), f"object {oid!r}: primitives")
    for i, (raw, pose) in enumerate(
        zip(primitives, _poses(obj, "primitive_poses", len(primitives), oid), strict=True)
    ):
        kind, dims = _primitive(raw, oid, f"primitives[{i}]")
        out.append((make_shape(oid, kind, dims), base @ pose))
    meshes = _as_list(obj.get("meshes"), f"object {oid!r}: meshes")
    for i, (raw, pose) in enumerate(
        zip(meshes, _poses(obj, "mesh_poses", len(meshes), oid), strict=True)
    ):
        vertices, faces = _mesh(raw, oid, f"meshes[{i}]")
        out.append((make_shape(oid, ShapeKind.MESH, (), vertices, faces), base @ pose))
    return out


def parse_moveit_objects(
    payload: Mapping[str, Any], frames: SceneFrames = NO_FRAMES
) -> list[SceneObject]:
    """Scene objects from a PlanningScene world; REMOVE entries are skipped, APPEND extends."""
    groups: dict[str, list[tuple[Any, FloatArray]]] = {}
    for n, obj in enumerate(collision_objects(payload)):
        if not isinstance(obj, Mapping):
            raise SceneError(f"collision_objects[{n}] must be a mapping")
        oid = obj.get("id")
        if not isinstance(oid, str) or not oid.strip() or len(oid) > 200:
            raise SceneError(f"collision_objects[{n}]: id must be a non-empty string")
        op = _enum(obj.get("operation", ADD), _OPERATION_NAMES, f"object {oid!r}: operation")
        if op == REMOVE:
            continue
        if op == MOVE:
            raise SceneError(f"object {oid!r}: operation MOVE is not valid in a full scene")
        if op == ADD and oid in groups:
            raise SceneError(f"duplicate object id {oid!r}")
        if op not in (ADD, APPEND):
            raise SceneError(f"object {oid!r}: unknown operation {op}")
        shapes = object_shapes(obj, oid, frames=frames)
        if not shapes:
            raise SceneError(f"object {oid!r}: no primitives or meshes")
        groups.setdefault(oid, []).extend(shapes)
    objects = [part for oid, shapes in groups.items() for part in parts(oid, shapes)]
    if len(objects) > MAX_OBJECTS:
        raise SceneError(f"a scene may hold at most {MAX_OBJECTS} objects")
    return objects


def parts(oid: str, shapes: Sequence[tuple[Any, FloatArray]]) -> list[SceneObject]:
    return [
        SceneObject(oid if i == 0 else f"{oid}#{i}", shape, pose)
        for i, (shape, pose) in enumerate(shapes)
    ]


def parse_planning_scene(
    payload: Mapping[str, Any], env: Mapping[str, float], frames: SceneFrames = NO_FRAMES
) -> Scene:
    """A scene from a PlanningScene message: world objects (in world frames or `frames`),
    attached objects and the allowed collision matrix; what is not applied is listed in the
    scene's warnings."""
    warnings: list[str] = []
    objects = parse_moveit_objects(payload, frames) if _has_world(payload) else []
    attached = _attached_objects(payload.get("robot_state"), warnings)
    allowed = parse_matrix(payload.get("allowed_collision_matrix"), warnings)
    if payload.get("is_diff"):
        raise SceneError(
            "is_diff: true: a scene diff changes a robot's current scene; send it to "
            "PUT /v1/robots/{robot_id}/scene, or send the whole scene with is_diff: false"
        )
    warnings += unapplied_warnings(payload)
    return make_scene(objects, env, allowed=allowed, attached=attached, warnings=warnings)


def unapplied_warnings(payload: Mapping[str, Any]) -> list[str]:
    """What MoveIt would apply from the message and this service does not."""
    return [
        f"{key}: {what}"
        for key, what in (
            ("link_padding", "link padding is not applied (checks are exact, without padding)"),
            ("link_scale", "link scale is not applied"),
            ("fixed_frame_transforms", "fixed frame transforms are not applied"),
        )
        if payload.get(key)
    ]


def is_planning_scene(payload: Mapping[str, Any]) -> bool:
    """Whether a scene document is a MoveIt PlanningScene (not the native form)."""
    return "objects" not in payload and any(
        key in payload for key in ("world", "collision_objects", "robot_state")
    )


def _has_world(payload: Mapping[str, Any]) -> bool:
    return "world" in payload or "collision_objects" in payload


def _attached_objects(state: Any, warnings: list[str]) -> list[AttachedObject]:
    if state is None:
        return []
    if not isinstance(state, Mapping):
        raise SceneError("robot_state must be a mapping")
    for key in ("joint_state", "multi_dof_joint_state"):
        value = state.get(key)
        if isinstance(value, Mapping) and any(
            value.get(k) for k in ("name", "position", "joint_names", "transforms")
        ):
            warnings.append(
                f"robot_state.{key} is not used: each plan request gives its own start state"
            )
    out: list[AttachedObject] = []
    for n, raw in enumerate(
        _as_list(state.get("attached_collision_objects"), "attached_collision_objects")
    ):
        op, _, oid, objects = parse_attached_entry(
            raw, f"robot_state.attached_collision_objects[{n}]"
        )
        if op == REMOVE:
            continue
        if op != ADD:
            raise SceneError(f"attached object {oid!r}: only operation ADD is supported")
        out += objects
    return out


def parse_attached_entry(raw: Any, where: str) -> tuple[int, str, str, list[AttachedObject]]:
    """One AttachedCollisionObject: its operation, link, object id and (for ADD) its parts.

    A REMOVE may leave the link or the id empty (all objects of a link, or all)."""
    if not isinstance(raw, Mapping):
        raise SceneError(f"{where} must be a mapping")
    link = raw.get("link_name")
    obj = raw.get("object")
    if not isinstance(obj, Mapping):
        raise SceneError(f"{where}: object must be a CollisionObject")
    oid = obj.get("id")
    if not isinstance(oid, str) or len(oid) > 200:
        raise SceneError(f"{where}: object.id must be a string")
    op = _enum(obj.get("operation", ADD), _OPERATION_NAMES, f"object {oid!r}: operation")
    if not isinstance(link, str):
        raise SceneError(f"{where}: link_name must name a robot link")
    if op == REMOVE:
        return op, link, oid, []
    if not link:
        raise SceneError(f"{where}: link_name must name a robot link")
    if not oid.strip():
        raise SceneError(f"{where}: object.id must be a non-empty string")
    if op != ADD:
        return op, link, oid, []
    shapes = object_shapes(obj, oid, link)
    if not shapes:
        raise SceneError(f"attached object {oid!r}: no primitives or meshes")
    touch = _as_list(raw.get("touch_links"), f"{where}.touch_links")
    if not all(isinstance(t, str) and t for t in touch):
        raise SceneError(f"{where}: touch_links must be link names")
    return op, link, oid, [AttachedObject(link, part, tuple(touch)) for part in parts(oid, shapes)]


def parse_matrix(matrix: Any, warnings: list[str]) -> list[tuple[str, str]]:
    if matrix is None:
        return []
    if not isinstance(matrix, Mapping):
        raise SceneError("allowed_collision_matrix must be a mapping")
    names = _as_list(matrix.get("entry_names"), "allowed_collision_matrix.entry_names")
    rows = _as_list(matrix.get("entry_values"), "allowed_collision_matrix.entry_values")
    if not all(isinstance(name, str) and name for name in names):
        raise SceneError("allowed_collision_matrix.entry_names must be names")
    if len(rows) != len(names):
        raise SceneError(
            f"allowed_collision_matrix has {len(names)} entry_names but {len(rows)} entry_values"
        )
    pairs: list[tuple[str, str]] = []
    for i, row in enumerate(rows):
        where = f"allowed_collision_matrix.entry_values[{i}]"
        enabled = row.get("enabled") if isinstance(row, Mapping) else row
        flags = _as_list(enabled, f"{where}.enabled")
        if len(flags) != len(names):
            raise SceneError(f"{where}.enabled has {len(flags)} values for {len(names)} names")
        for j, flag in enumerate(flags):
            if not isinstance(flag, bool | int):
                raise SceneError(f"{where}.enabled[{j}] must be true or false")
            if flag and i != j:
                pairs.append((names[i], names[j]))
    if any(_as_list(matrix.get("default_entry_values"), "default_entry_values")):
        warnings.append(
            "allowed_collision_matrix.default_entry_values are not applied: list the pairs "
            "in entry_values"
        )
    return pairs


def _pose_msg(pose: FloatArray) -> dict[str, dict[str, float]]:
    x, y, z = (float(v) for v in pose[:3, 3])
    qx, qy, qz, qw = (float(v) for v in matrix_to_quaternion(pose))
    return {
        "position": {"x": x, "y": y, "z": z},
        "orientation": {"x": qx, "y": qy, "z": qz, "w": qw},
    }


_IDENTITY_MSG = _pose_msg(np.eye(4))


def _collision_object(obj: SceneObject, frame_id: str) -> dict[str, Any]:
    shape = obj.shape
    msg: dict[str, Any] = {
        "header": {"frame_id": frame_id},
        "id": obj.id,
        "pose": _pose_msg(obj.pose),
        "primitives": [],
        "primitive_poses": [],
        "meshes": [],
        "mesh_poses": [],
        "planes": [],
        "plane_poses": [],
        "operation": ADD,
    }
    if shape.kind is ShapeKind.MESH:
        assert shape.vertices is not None and shape.faces is not None
        msg["meshes"].append(
            {
                "triangles": [{"vertex_indices": [int(i) for i in f]} for f in shape.faces],
                "vertices": [
                    {"x": float(a), "y": float(b), "z": float(c)} for a, b, c in shape.vertices
                ],
            }
        )
        msg["mesh_poses"].append(_IDENTITY_MSG)
        return msg
    if shape.kind is ShapeKind.BOX:
        prims = [(BOX, list(shape.size), 0.0)]
    elif shape.kind is ShapeKind.SPHERE:
        prims = [(SPHERE, list(shape.size), 0.0)]
    else:  # cylinder; a capsule (no MoveIt primitive) becomes a cylinder plus two end spheres
        radius, length = shape.size
        prims = [(CYLINDER, [length, radius], 0.0)]
        if shape.kind is ShapeKind.CAPSULE:
            prims += [(SPHERE, [radius], -length / 2), (SPHERE, [radius], length / 2)]
    for code, dims, dz in prims:
        msg["primitives"].append({"type": code, "dimensions": [float(v) for v in dims]})
        offset = np.eye(4)
        offset[2, 3] = dz
        msg["primitive_poses"].append(_pose_msg(offset))
    return msg


def scene_to_moveit(scene: Scene, *, frame_id: str = "world", name: str = "") -> dict[str, Any]:
    """The scene as a PlanningScene message dict (capsules become cylinder + spheres)."""
    return {
        "name": name,
        "is_diff": False,
        "world": {"collision_objects": [_collision_object(o, frame_id) for o in scene.objects]},
    }
