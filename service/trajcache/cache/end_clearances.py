"""The clearances of stored paths' end segments this process measured.

A hit replaces a stored path's first and last states; `geometry/validation/end_clearance.py`
proves most of each new end segment from the clearance measured along the stored one. They are
measured by the record writer, off the request path (`services.plan.certified`: after a path is
planned and stored, and after a hit on one whose ends had none here), and kept here, bounded, by the
model variant, the validator settings and the exact bits of the segment's two states, with the
scene they were measured in: its hash, and each object's shape digest and pose. A segment
looked up the other way round finds its clearance reversed.

In the scene they were measured in, they hold as measured. In another scene whose every object
has an id and a shape digest (shape, sizes, allowed names) of that scene's, each moved by at
most δ (`certificates.moved_by`; `moves_by`, all at once), the clearance to the scene is at
least the measured one less the largest δ (distance is 1-Lipschitz in every point of every
object); the robot pairs' part does not depend on the scene. Any other scene (an object added,
reshaped or allowed to touch something else) gets none.
"""

from __future__ import annotations

import hashlib
import threading
from dataclasses import dataclass

import numpy as np

from trajcache.cache.memo import MemoScope
from trajcache.core.lru import LRU
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.certificates import moves_by, shape_digests
from trajcache.geometry.validation.end_clearance import CAP, SegmentClearance

__all__ = ["EndClearances"]

_Key = tuple[str, tuple[object, ...], bytes]  # model variant, validator settings, segment


@dataclass(frozen=True)
class _Measured:
    clearance: SegmentClearance
    scene_hash: str
    objects: dict[str, tuple[str, FloatArray]]  # id → (shape digest, pose)


class EndClearances:
    """Thread-safe LRU of segment clearances by variant, settings and segment, bounded in
    bytes."""

    def __init__(self, max_bytes: int = 32 * 1024 * 1024) -> None:
        self._entries: LRU[_Key, _Measured] = LRU(max_size=max_bytes, size_fn=_size)
        self._slacks: LRU[tuple[str, str], float] = LRU(capacity=1024)  # by the scenes' hashes
        # Segments queued for measuring, by scene hash; a claim whose job never ran expires.
        self._queued: LRU[tuple[_Key, str], bool] = LRU(capacity=4096, ttl_s=60.0)
        self._lock = threading.Lock()  # a claim's look and put are one step

    def put(
        self, scope: MemoScope, segment: FloatArray, clearance: SegmentClearance, scene: Scene
    ) -> None:
        """Keep the clearance measured along `segment` (2, D) in `scope`, whose scene is
        `scene`."""
        shapes = shape_digests(scene)
        objects = {o.id: (shapes[o.id], np.array(o.pose, dtype=float)) for o in scene.objects}
        self._entries.put(_key(scope, segment), _Measured(clearance, scope.scene_hash, objects))

    def get(self, scope: MemoScope, segment: FloatArray, scene: Scene) -> SegmentClearance | None:
        """The clearance of `segment` (2, D), run either way, that holds in `scope`'s scene
        `scene` (module docstring); None if there is none."""
        found = self._entries.get(_key(scope, segment))
        backwards = found is None
        if backwards:
            found = self._entries.get(_key(scope, segment[::-1]))
        if found is None:
            return None
        clearance = found.clearance.reversed() if backwards else found.clearance
        if found.scene_hash == scope.scene_hash:
            return clearance
        slack = self._slack(found, scene)
        return None if slack is None else clearance.less(slack)

    def claim(self, scope: MemoScope, segment: FloatArray) -> bool:
        """Whether the caller is the first to queue a measurement of `segment` (2, D), either
        way round, in `scope`'s scene; True once more after `release`."""
        forward, backward = _key(scope, segment), _key(scope, segment[::-1])
        with self._lock:
            if (forward, scope.scene_hash) in self._queued or (
                backward,
                scope.scene_hash,
            ) in self._queued:
                return False
            self._queued.put((forward, scope.scene_hash), True)
            return True

    def release(self, scope: MemoScope, segment: FloatArray) -> None:
        """`segment`'s measurement in `scope`'s scene ended, kept or not."""
        self._queued.discard((_key(scope, segment), scope.scene_hash))

    def clear(self) -> None:
        """Forget everything."""
        self._entries.clear()
        self._slacks.clear()
        self._queued.clear()

    def __len__(self) -> int:
        return len(self._entries)

    def _slack(self, measured: _Measured, scene: Scene) -> float | None:
        """The most an object of `scene` moved from where it was measured; None when one is
        new or other, or moved by `CAP` or more (nothing is left to prove with)."""
        key = (measured.scene_hash, scene.hash)
        known = self._slacks.get(key) if scene.hash else None
        if known is not None:
            return None if known < 0 else known
        slack = _largest_move(measured, scene)
        if scene.hash:
            self._slacks.put(key, -1.0 if slack is None else slack)
        return slack


def _largest_move(measured: _Measured, scene: Scene) -> float | None:
    shapes = shape_digests(scene)
    before = []
    for obj in scene.objects:
        then = measured.objects.get(obj.id)
        if then is None or then[0] != shapes[obj.id]:
            return None
        before.append(then[1])
    if not before:
        return 0.0
    after = np.stack([np.asarray(o.pose, dtype=float) for o in scene.objects])
    radii = np.array([o.shape.bounding_radius() for o in scene.objects])
    slack = float(moves_by(np.stack(before), after, radii).max())
    return None if slack >= CAP else slack


def _key(scope: MemoScope, segment: FloatArray) -> _Key:
    array = np.ascontiguousarray(segment, dtype=np.float64)
    return scope.model_id, scope.settings, hashlib.sha256(array.tobytes()).digest()


def _size(measured: _Measured) -> int:
    c = measured.clearance
    return c.fractions.nbytes + c.scene.nbytes + c.pairs.nbytes + 256 * (1 + len(measured.objects))
