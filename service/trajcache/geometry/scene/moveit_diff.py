"""A MoveIt `PlanningScene` with `is_diff: true`, applied to the robot's current scene.

MoveIt reads such a message as changes to the scene it already has (`PlanningScene::
setPlanningSceneDiffMsg`), and so does this module; it is never taken as the whole scene, which
would silently drop every obstacle the diff does not mention.

- `world.collision_objects`, in order, by operation:
  - ADD puts the object, replacing one of the same id (all its shapes);
  - REMOVE takes the object away; an empty id takes every world object away. Removing an id
    that is not in the scene changes nothing and is reported in the warnings, as MoveIt logs it;
  - APPEND adds shapes to the object, or creates it;
  - MOVE is refused (422): MoveIt moves the object's own frame and keeps each shape's pose in
    it, but a stored scene keeps each shape's world pose only, so the shapes could not be moved
    as MoveIt moves them. Send the object again with ADD, which replaces it.
- `robot_state.attached_collision_objects`: with `robot_state.is_diff` each entry is applied
  (ADD puts or replaces the attached object; REMOVE detaches by id, or all of `link_name`, or
  all); without it, as in MoveIt, the listed objects replace the attached ones (ADD only).
  MoveIt leaves a detached object in the world where the robot held it. This service does not
  know where that is (each plan gives its own state), so a detach must say it: the same diff
  gives the object's world pose (ADD) or removes it from the world (REMOVE); otherwise 422.
- `allowed_collision_matrix` with any `entry_names` replaces the scene's allowed pairs, as in
  MoveIt; without entries the allowed pairs stay.
- `env` values given replace those keys; the others stay.

What MoveIt applies and this service does not (link padding and scale, fixed frame transforms,
the robot state's joint values) is listed in the warnings, as for a whole scene.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.shapes import FloatArray, Shape
from trajcache.geometry.scene.fields import parse_env
from trajcache.geometry.scene.frames import NO_FRAMES, SceneFrames
from trajcache.geometry.scene.moveit import (
    ADD,
    APPEND,
    MOVE,
    REMOVE,
    collision_objects,
    enum_operation,
    is_planning_scene,
    object_shapes,
    parse_attached_entry,
    parse_matrix,
    parts,
    unapplied_warnings,
)
from trajcache.geometry.scene.scene import AttachedObject, Scene, make_scene

Shapes = list[tuple[Shape, FloatArray]]


def is_scene_diff(payload: Mapping[str, Any]) -> bool:
    """Whether `payload` is a MoveIt PlanningScene marked `is_diff: true`."""
    return is_planning_scene(payload) and bool(payload.get("is_diff"))


def _world_groups(scene: Scene) -> dict[str, Shapes]:
    """The scene's world objects as MoveIt objects: parts `id`, `id#1` … under `id`, in order."""
    groups: dict[str, Shapes] = {}
    for obj in scene.objects:
        groups.setdefault(obj.id.partition("#")[0], []).append((obj.shape, obj.pose))
    return groups


def _attached_groups(scene: Scene) -> dict[str, list[AttachedObject]]:
    groups: dict[str, list[AttachedObject]] = {}
    for held in scene.attached:
        groups.setdefault(held.object.id.partition("#")[0], []).append(held)
    return groups


def _apply_world(
    groups: dict[str, Shapes], payload: Mapping[str, Any], warnings: list[str], frames: SceneFrames
) -> set[str]:
    """Apply the world's collision objects to `groups`; return the ids the diff names."""
    named: set[str] = set()
    for n, obj in enumerate(collision_objects(payload)):
        if not isinstance(obj, Mapping):
            raise SceneError(f"collision_objects[{n}] must be a mapping")
        oid = obj.get("id")
        if not isinstance(oid, str) or len(oid) > 200:
            raise SceneError(f"collision_objects[{n}]: id must be a string")
        op = enum_operation(obj.get("operation", ADD), f"object {oid!r}: operation")
        if op == REMOVE:
            named.add(oid)
            if not oid:
                groups.clear()
            elif groups.pop(oid, None) is None:
                warnings.append(f"REMOVE of object {oid!r}: not in the scene, nothing removed")
            continue
        if not oid.strip():
            raise SceneError(f"collision_objects[{n}]: id must be a non-empty string")
        if op == MOVE:
            raise SceneError(
                f"object {oid!r}: operation MOVE is not applied (the stored scene keeps each "
                "shape's world pose, not the object's own frame, so its shapes cannot be moved "
                "as MoveIt moves them); send the object again with operation ADD, which replaces it"
            )
        if op not in (ADD, APPEND):
            raise SceneError(f"object {oid!r}: unknown operation {op}")
        shapes = object_shapes(obj, oid, frames=frames)
        if not shapes:
            raise SceneError(f"object {oid!r}: no primitives or meshes")
        named.add(oid)
        if op == ADD:
            groups[oid] = shapes
        else:
            groups.setdefault(oid, []).extend(shapes)
    return named


def _apply_attached(
    held: dict[str, list[AttachedObject]], state: Any, world_named: set[str]
) -> dict[str, list[AttachedObject]]:
    """The attached objects after the robot state's entries (see the module docstring)."""
    if state is None:
        return held
    if not isinstance(state, Mapping):
        raise SceneError("robot_state must be a mapping")
    entries = state.get("attached_collision_objects") or []
    if not isinstance(entries, list):
        raise SceneError("robot_state.attached_collision_objects must be a list")
    as_diff = bool(state.get("is_diff"))
    if not as_diff and not _state_given(state):
        return held  # an empty robot state changes nothing in a diff
    out = dict(held) if as_diff else {}
    for n, raw in enumerate(entries):
        where = f"robot_state.attached_collision_objects[{n}]"
        op, link, oid, objects = parse_attached_entry(raw, where)
        if op == ADD:
            out[oid] = objects
            continue
        if op != REMOVE:
            raise SceneError(
                f"attached object {oid!r}: only operations ADD and REMOVE are supported"
            )
        if not as_diff:
            raise SceneError(
                f"{where}: operation REMOVE needs robot_state.is_diff: true (MoveIt only adds "
                "attached objects from a robot state that is not a diff)"
            )
        gone = [
            key
            for key, group in out.items()
            if (key == oid if oid else (not link or group[0].link == link))
        ]
        for key in gone:
            if key not in world_named:
                raise SceneError(
                    f"attached object {key!r} is detached, but the diff does not say where it is "
                    "now: MoveIt would leave it in the world where the robot holds it; add it to "
                    "world.collision_objects with its pose (ADD), or remove it there (REMOVE)"
                )
            del out[key]
    return out


def _state_given(state: Mapping[str, Any]) -> bool:
    """Whether a robot state says anything (MoveIt applies a non-diff state only then)."""
    if state.get("attached_collision_objects"):
        return True
    for key in ("joint_state", "multi_dof_joint_state"):
        value = state.get(key)
        if isinstance(value, Mapping) and any(
            value.get(k) for k in ("name", "position", "joint_names", "transforms")
        ):
            return True
    return False


def apply_scene_diff(
    current: Scene, payload: Mapping[str, Any], frames: SceneFrames = NO_FRAMES
) -> Scene:
    """`current` with the PlanningScene diff `payload` applied (see the module docstring)."""
    warnings: list[str] = []
    groups = _world_groups(current)
    named = _apply_world(groups, payload, warnings, frames)
    before = _attached_groups(current)
    held = _apply_attached(before, payload.get("robot_state"), named)
    dropped = sorted(set(before) - set(held) - named)
    if dropped:
        warnings.append(
            f"attached objects {dropped} are no longer attached: robot_state is not a diff "
            "(is_diff: false), so its attached objects replace the scene's, as in MoveIt"
        )
    allowed: Any = current.allowed
    matrix = payload.get("allowed_collision_matrix")
    if isinstance(matrix, Mapping) and matrix.get("entry_names"):
        allowed = parse_matrix(matrix, warnings)
    elif matrix is not None and not isinstance(matrix, Mapping):
        raise SceneError("allowed_collision_matrix must be a mapping")
    warnings += unapplied_warnings(payload)
    env = {**current.env, **parse_env(payload.get("env"))}
    objects = [part for oid, shapes in groups.items() for part in parts(oid, shapes)]
    return make_scene(
        objects,
        env,
        allowed=allowed,
        attached=[a for group in held.values() for a in group],
        warnings=warnings,
    )
