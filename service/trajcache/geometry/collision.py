"""Batched collision checking of robot states against a scene and against the robot itself.

A check runs in two phases. The broad phase is vectorized over every state, element and
obstacle at once: each collision element is bounded by a sphere around its frame origin and
each scene object by its oriented box, so one numpy pass gives a lower bound on every
element-object and element-element distance. Only pairs whose bound falls below the required
clearance reach FCL's narrow phase, one call per pair.

Clearance: with `pad` > 0 a pair counts as AMBIGUOUS when its true distance is in (0, pad];
the certified validator resolves those by subdividing the motion.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from enum import Enum

import fcl
import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.kinematics import element_transforms, link_transforms
from trajcache.geometry.robot import RobotModel
from trajcache.geometry.scene import Scene
from trajcache.geometry.shapes import FloatArray

IntArray = NDArray[np.int64]

FREE, AMBIGUOUS, COLLIDING = 1, 0, -1
_CACHE_SIZE = 64


class ContactKind(str, Enum):
    """What a robot link touched."""

    SCENE = "scene"
    SELF = "self"


@dataclass(frozen=True)
class Contact:
    """One colliding pair: a robot link and a scene object id or another link."""

    link: str
    other: str
    kind: ContactKind

    def describe(self) -> str:
        """Human-readable form used in error messages."""
        what = "object" if self.kind is ContactKind.SCENE else "link"
        return f"link '{self.link}' hits {what} '{self.other}'"


class RobotGeometry:
    """FCL geometry of a model's collision elements; built once per model and shared."""

    def __init__(self, model: RobotModel) -> None:
        self.model = model
        elements = model.elements
        self.geometries = [e.shape.to_fcl() for e in elements]
        self.element_link = np.array([e.link for e in elements], dtype=np.int64)
        self.radius = np.array([e.shape.bounding_radius() for e in elements], dtype=float)
        allowed = model.allowed_pairs
        pairs = [
            (i, j)
            for i in range(len(elements))
            for j in range(i + 1, len(elements))
            if elements[i].link != elements[j].link
            and (min(elements[i].link, elements[j].link), max(elements[i].link, elements[j].link))
            not in allowed
        ]
        self.pair_i = np.array([p[0] for p in pairs], dtype=np.int64)
        self.pair_j = np.array([p[1] for p in pairs], dtype=np.int64)
        self._local = threading.local()

    def objects(self) -> list[fcl.CollisionObject]:
        """This thread's FCL objects (transforms are mutated during a check)."""
        objs: list[fcl.CollisionObject] | None = getattr(self._local, "objects", None)
        if objs is None:
            objs = [fcl.CollisionObject(g, fcl.Transform()) for g in self.geometries]
            self._local.objects = objs
        return objs


class SceneGeometry:
    """FCL objects and oriented bounding boxes of one scene version; shared and read-only."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.ids = [o.id for o in scene.objects]
        self.objects = [
            fcl.CollisionObject(o.shape.to_fcl(), fcl.Transform(o.pose[:3, :3], o.pose[:3, 3]))
            for o in scene.objects
        ]
        count = len(scene.objects)
        self.rotation = np.array([o.pose[:3, :3] for o in scene.objects]).reshape(count, 3, 3)
        self.position = np.array([o.pose[:3, 3] for o in scene.objects]).reshape(count, 3)
        self.half = np.array([o.shape.half_extents() for o in scene.objects]).reshape(count, 3)
        # local = Rᵀ(c − t) for every object in one matmul: c @ [R_0 | R_1 | …] − tᵀR.
        self.rotation_cat = np.ascontiguousarray(self.rotation.transpose(1, 0, 2).reshape(3, -1))
        self.offset = np.einsum("mj,mji->mi", self.position, self.rotation)
        reach = np.einsum("mij,mj->mi", np.abs(self.rotation), self.half)
        self.aabb_lo, self.aabb_hi = self.position - reach, self.position + reach


class _LRU:
    """A small thread-safe LRU map used for per-model and per-scene geometry."""

    def __init__(self, size: int) -> None:
        self._size = size
        self._items: OrderedDict[str, object] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: str) -> object | None:
        with self._lock:
            item = self._items.get(key)
            if item is not None:
                self._items.move_to_end(key)
            return item

    def put(self, key: str, value: object) -> None:
        with self._lock:
            self._items[key] = value
            self._items.move_to_end(key)
            while len(self._items) > self._size:
                self._items.popitem(last=False)


_robots = _LRU(_CACHE_SIZE)
_scenes = _LRU(_CACHE_SIZE)


def robot_geometry(model: RobotModel) -> RobotGeometry:
    """The shared RobotGeometry of a model (cached by model id)."""
    cached = _robots.get(model.model_id)
    if isinstance(cached, RobotGeometry) and cached.model is model:
        return cached
    built = RobotGeometry(model)
    _robots.put(model.model_id, built)
    return built


def scene_geometry(scene: Scene) -> SceneGeometry:
    """The shared SceneGeometry of a scene version (cached by content hash)."""
    key = scene.hash or f"id:{id(scene)}"
    cached = _scenes.get(key)
    if isinstance(cached, SceneGeometry):
        return cached
    built = SceneGeometry(scene)
    _scenes.put(key, built)
    return built


@dataclass
class BatchVerdict:
    """Per-state outcome of a batch check: FREE, AMBIGUOUS or COLLIDING, and the first contact."""

    status: NDArray[np.int8]
    first_collision: int  # index of the first colliding state, or -1
    contacts: list[Contact]
    narrow_checks: int


class CollisionChecker:
    """Checks batches of states of one robot model in one scene."""

    def __init__(self, model: RobotModel, scene: Scene) -> None:
        self.model = model
        self.robot = robot_geometry(model)
        self.scene = scene_geometry(scene)
        self.narrow_checks = 0

    def element_poses(self, states: FloatArray) -> FloatArray:
        """World poses (N, E, 4, 4) of every collision element."""
        return element_transforms(self.model, link_transforms(self.model, states))

    def check(
        self,
        states: FloatArray,
        *,
        element_pad: FloatArray | None = None,
        pair_pad: FloatArray | None = None,
        stop_at_first: bool = True,
    ) -> BatchVerdict:
        """Classify each state; pads are (N, E) per element and (N, P) per self-collision pair."""
        poses = self.element_poses(states)
        n, e = poses.shape[:2]
        epad = np.zeros((n, e)) if element_pad is None else element_pad
        ppad = np.zeros((n, len(self.robot.pair_i))) if pair_pad is None else pair_pad
        centers = poses[:, :, :3, 3]
        scene_near = self._scene_candidates(centers, epad)
        self_near = self._self_candidates(centers, ppad)
        return self._narrow_phase(poses, epad, ppad, scene_near, self_near, stop_at_first)

    def _scene_candidates(self, centers: FloatArray, pad: FloatArray) -> IntArray:
        """(K, 3) rows (state, element, object) whose bounding distance is within the pad."""
        sg = self.scene
        if len(sg.ids) == 0:
            return np.empty((0, 3), dtype=np.int64)
        n, e = centers.shape[:2]
        # Cull objects far from everything this batch does: one AABB around all padded spheres.
        grow = (self.robot.radius[None, :] + pad)[..., None]
        lo, hi = (centers - grow).min(axis=(0, 1)), (centers + grow).max(axis=(0, 1))
        near = np.flatnonzero(np.all((sg.aabb_lo <= hi) & (sg.aabb_hi >= lo), axis=1))
        if len(near) == 0:
            return np.empty((0, 3), dtype=np.int64)
        rot = sg.rotation_cat.reshape(3, -1, 3)[:, near].reshape(3, -1)
        local = (centers.reshape(-1, 3) @ rot).reshape(n, e, len(near), 3) - sg.offset[near]
        outside = np.maximum(np.abs(local) - sg.half[near], 0.0)
        sq = outside[..., 0] ** 2 + outside[..., 1] ** 2 + outside[..., 2] ** 2
        bound = np.sqrt(sq) - self.robot.radius[None, :, None]
        rows = np.argwhere(bound <= pad[:, :, None])
        rows[:, 2] = near[rows[:, 2]]
        return rows

    def _self_candidates(self, centers: FloatArray, pad: FloatArray) -> IntArray:
        """(K, 2) rows (state, pair) whose bounding-sphere distance is within the pad."""
        rg = self.robot
        if len(rg.pair_i) == 0:
            return np.empty((0, 2), dtype=np.int64)
        gap = np.linalg.norm(centers[:, rg.pair_i] - centers[:, rg.pair_j], axis=-1)
        bound = gap - rg.radius[rg.pair_i] - rg.radius[rg.pair_j]
        return np.argwhere(bound <= pad)

    def _narrow_phase(
        self,
        poses: FloatArray,
        epad: FloatArray,
        ppad: FloatArray,
        scene_near: IntArray,
        self_near: IntArray,
        stop_at_first: bool,
    ) -> BatchVerdict:
        n = poses.shape[0]
        status = np.full(n, FREE, dtype=np.int8)
        # Merge both candidate lists in state order so that the first collision stops the scan.
        rows = np.concatenate(
            [
                np.column_stack([scene_near, np.zeros(len(scene_near), dtype=np.int64)]),
                np.column_stack(
                    [
                        self_near[:, 0],
                        self_near[:, 1],
                        np.full(len(self_near), -1),
                        np.ones(len(self_near), dtype=np.int64),
                    ]
                ).astype(np.int64),
            ]
        )
        rows = rows[np.argsort(rows[:, 0], kind="stable")]
        objs = self.robot.objects()
        rg, sg = self.robot, self.scene
        dreq, creq = fcl.DistanceRequest(), fcl.CollisionRequest()
        contacts: list[Contact] = []
        checks = 0
        first = -1
        posed = [-1] * len(objs)  # the state each element's FCL object is currently posed at
        for s, a, b, is_self in rows.tolist():
            if is_self:
                i, j = int(rg.pair_i[a]), int(rg.pair_j[a])
                for k in (i, j):
                    if posed[k] != s:
                        _set_pose(objs[k], poses[s, k])
                        posed[k] = s
                pad = float(ppad[s, a])
                other = objs[j]
                first_obj = objs[i]
            else:
                if posed[a] != s:
                    _set_pose(objs[a], poses[s, a])
                    posed[a] = s
                pad = float(epad[s, a])
                other = sg.objects[b]
                first_obj = objs[a]
            checks += 1
            if pad <= 0.0:
                hit = fcl.collide(first_obj, other, creq, fcl.CollisionResult()) > 0
                verdict = COLLIDING if hit else FREE
            else:
                dist = fcl.distance(first_obj, other, dreq, fcl.DistanceResult())
                verdict = COLLIDING if dist < 0.0 else (AMBIGUOUS if dist <= pad else FREE)
            if verdict == COLLIDING:
                status[s] = COLLIDING
                contacts.append(self._contact(a, b, bool(is_self)))
                if first < 0:
                    first = s
                if stop_at_first:
                    break
            elif verdict == AMBIGUOUS:
                status[s] = AMBIGUOUS
        self.narrow_checks += checks
        return BatchVerdict(
            status=status, first_collision=first, contacts=contacts, narrow_checks=checks
        )

    def _contact(self, a: int, b: int, is_self: bool) -> Contact:
        names = self.model.link_names
        rg = self.robot
        if is_self:
            li, lj = rg.element_link[rg.pair_i[a]], rg.element_link[rg.pair_j[a]]
            return Contact(link=names[li], other=names[lj], kind=ContactKind.SELF)
        return Contact(
            link=names[rg.element_link[a]], other=self.scene.ids[b], kind=ContactKind.SCENE
        )

    def state_contacts(self, state: FloatArray) -> list[Contact]:
        """Every contact of one state (for error messages naming links and objects)."""
        verdict = self.check(np.asarray(state, dtype=float)[None, :], stop_at_first=False)
        unique: dict[tuple[str, str], Contact] = {}
        for c in verdict.contacts:
            unique.setdefault((c.link, c.other), c)
        return list(unique.values())


def _set_pose(obj: fcl.CollisionObject, pose: FloatArray) -> None:
    obj.setTranslation(pose[:3, 3])
    obj.setRotation(pose[:3, :3])
