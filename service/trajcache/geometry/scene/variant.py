"""The model a robot is checked with: its registered model, as the robot holds it in its scene.

Three things a robot or its scene may change, each giving a variant with its own model id (so
geometry, validators and validation verdicts are never shared with another variant):
- held joint values set for the robot (a gripper held open instead of closed); mimic joints
  follow their leader again;
- the scene's attached objects, each a link of its own, fixed to the link that carries it. As in
  MoveIt, an attached object is checked against every link but that one and its `touch_links`;
- the scene's allowed pairs of two robot links (or a link and an attached object), added to the
  model's skipped pairs with the reason `scene`.

Pairs the scene allows between a link and a world object are not part of the model: the
distance bounds leave them out (`Clearance`).

A variant built once is found again by the registered model, the scene's content hash and the
held values, without its key: the hash covers the attached objects and the allowed pairs, as it
does for the validators, which are keyed by it too.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from trajcache.core.lru import LRU
from trajcache.geometry.errors import SceneError, StateError
from trajcache.geometry.model.robot import CollisionElement, KinematicJoint, RobotModel
from trajcache.geometry.scene.scene import Scene

VARIANT_CACHE_SIZE = 256

VariantCache = LRU[tuple[str, str], RobotModel]  # by (registered model id, variant key)


def variant_cache(capacity: int = VARIANT_CACHE_SIZE) -> VariantCache:
    """An empty cache of built variants."""
    return LRU(capacity=capacity)


def model_in_scene(
    model: RobotModel,
    scene: Scene,
    held: Mapping[str, float] | None = None,
    *,
    cache: VariantCache | None = None,
) -> RobotModel:
    """`model` with the robot's `held` joint values, the scene's attached objects and its
    allowed link pairs (the model itself when none of them applies); built once per `cache`,
    or every time without one."""
    if not held and not scene.attached and not scene.allowed:
        return model  # the common case, on every plan: nothing to look at
    # A scene's content hash names its attached objects and allowed pairs: with the held
    # values, it finds the variant again without computing its key (a sort, JSON and SHA-256).
    known = None
    if cache is not None and scene.hash:
        known = (model.model_id, f"scene {scene.hash} {sorted((held or {}).items())!r}")
        if (found := cache.get(known)) is not None:
            return found
    links = set(model.link_names)
    robot_pairs = sorted((a, b) for a, b in scene.allowed if a in links and b in links and a != b)
    if not held and not scene.attached and not robot_pairs:
        variant = model
    else:
        key = (model.model_id, _variant_key(scene, robot_pairs, held or {}))
        if cache is None:
            return _build(model, scene, robot_pairs, held or {}, key[1])
        variant = cache.get_or_build(
            key, lambda: _build(model, scene, robot_pairs, held or {}, key[1])
        )
    if cache is not None and known is not None:
        cache.put(known, variant)
    return variant


def _variant_key(
    scene: Scene, robot_pairs: list[tuple[str, str]], held: Mapping[str, float]
) -> str:
    attached = [
        {
            "id": a.object.id,
            "link": a.link,
            "touch": sorted(a.touch_links),
            "shape": a.object.shape.canonical(),
            "pose": [round(float(v), 9) for v in a.object.pose[:3].ravel()],
        }
        for a in sorted(scene.attached, key=lambda a: a.object.id)
    ]
    doc = {
        "held": {k: repr(float(v)) for k, v in sorted(held.items())},
        "attached": attached,
        "allowed": robot_pairs,
    }
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _build(
    model: RobotModel,
    scene: Scene,
    robot_pairs: list[tuple[str, str]],
    held: Mapping[str, float],
    key: str,
) -> RobotModel:
    joints = _held_joints(model, held) if held else model.joints
    names = list(model.link_names)
    index = {name: i for i, name in enumerate(names)}
    elements = list(model.elements)
    extra_joints: list[KinematicJoint] = []
    reasons = dict(model.pair_reasons)
    for attached in scene.attached:
        parent = index.get(attached.link)
        if parent is None:
            raise SceneError(
                f"attached object {attached.object.id!r}: the robot has no link {attached.link!r}"
            )
        if attached.object.id in index:
            raise SceneError(f"attached object {attached.object.id!r} has the name of a robot link")
        child = len(names)
        names.append(attached.object.id)
        index[attached.object.id] = child
        extra_joints.append(
            KinematicJoint(
                name=f"attach:{attached.object.id}",
                kind="fixed",
                parent=parent,
                child=child,
                origin=np.asarray(attached.object.pose, dtype=float),
                axis=np.array([1.0, 0.0, 0.0]),
            )
        )
        elements.append(CollisionElement.placed(child, attached.object.shape, np.eye(4)))
        for other in (attached.link, *attached.touch_links):
            if other in index and index[other] != child:
                reasons[_pair(index[other], child)] = "scene"
    for a, b in robot_pairs:
        reasons.setdefault(_pair(index[a], index[b]), "scene")
    for a, b in scene.allowed:  # an attached object and a link (or another attached object)
        if a in index and b in index and a != b and (a, b) not in robot_pairs:
            reasons.setdefault(_pair(index[a], index[b]), "scene")
    return replace(
        model,
        model_id=hashlib.sha256(f"{model.model_id}:{key}".encode()).hexdigest(),
        link_names=tuple(names),
        joints=(*joints, *extra_joints),
        elements=tuple(elements),
        pair_reasons=reasons,
        held_values=_held_values(joints),
    )


def _pair(a: int, b: int) -> tuple[int, int]:
    return min(a, b), max(a, b)


def _held_joints(model: RobotModel, held: Mapping[str, float]) -> tuple[KinematicJoint, ...]:
    """The joints with `held` values set; StateError names a value that cannot be held."""
    by_name = {j.name: j for j in model.joints}
    for name, value in held.items():
        joint = by_name.get(name)
        if joint is None or joint.kind == "fixed":
            raise StateError(f"joint_values: {name!r} is not a movable joint of the model")
        if joint.index >= 0:
            raise StateError(
                f"joint_values: {name!r} is a planning joint; its value comes with each state"
            )
        if joint.mimic is not None:
            raise StateError(f"joint_values: {name!r} mimics {joint.mimic[0]!r}; give that joint")
        if not math.isfinite(value):
            raise StateError(f"joint_values: {name!r} is not finite")
        if joint.bounds is not None and joint.kind != "continuous":
            lo, hi = joint.bounds
            if not lo - 1e-9 <= value <= hi + 1e-9:
                raise StateError(f"joint_values: {name} = {value:.6g} not in [{lo:.6g}, {hi:.6g}]")
    values = {j.name: j.default for j in model.joints if j.index < 0 and j.kind != "fixed"}
    values.update({k: float(v) for k, v in held.items()})
    for _ in range(len(values)):  # followers of followers settle within as many rounds
        for joint in model.joints:
            if joint.mimic is not None and joint.index < 0:
                leader, multiplier, offset = joint.mimic
                values[joint.name] = multiplier * values.get(leader, 0.0) + offset
    return tuple(
        replace(j, default=values[j.name]) if j.name in values else j for j in model.joints
    )


def _held_values(joints: tuple[KinematicJoint, ...]) -> dict[str, float]:
    return {j.name: j.default for j in joints if j.index < 0 and j.kind != "fixed"}
