"""Scenes: collision objects in the world frame plus named environment values.

A scene may also carry what the robot team says about contact in it, which is part of its hash:
- `allowed_collisions`: pairs of names whose contact is allowed, as a MoveIt allowed collision
  matrix gives them: a link and an object (a part the hand holds, a table the base stands on),
  or two links (adjusting the model's matrix for this scene). An object id also covers the
  parts `id#1`, `id#2` … of a multi-shape object.
- `attached_objects`: objects that travel with a link (posed in the link frame, with the links
  they may touch); they are checked against the scene and against the robot's other links.

Scenes come from documents through `parse.py` (the native payload of `payload.py`, or a MoveIt
`PlanningScene`, `moveit.py`).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.scene.fields import parse_env

MAX_OBJECTS = 10_000
MAX_ALLOWED_PAIRS = 10_000


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


def object_reach(obj: SceneObject) -> float:
    """How far from the origin of its frame (the world, or an attached object's link) the object
    can reach: its position's distance plus its shape's bounding radius (inf on overflow)."""
    with np.errstate(over="ignore"):
        return float(np.linalg.norm(obj.pose[:3, 3])) + obj.shape.bounding_radius()


def farthest_object(scene: Scene) -> tuple[SceneObject, float] | None:
    """The object (attached ones included) that reaches farthest, and its reach; None if empty."""
    objects = (*scene.objects, *(a.object for a in scene.attached))
    if not objects:
        return None
    reaches = [object_reach(obj) for obj in objects]
    i = int(np.argmax(reaches))
    return objects[i], reaches[i]


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
