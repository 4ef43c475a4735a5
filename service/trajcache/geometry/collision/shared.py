"""The shared geometry of a model and of a scene: built once, cached, and shared read-only.

A model's `RobotGeometry` leaves out the self-collision pairs proven free within the joint limits
(`free_pairs.py`); the proof poses the geometry through the distance bounds and narrow phase,
which is why it is applied here, above them, and not where the geometry is built (`bodies.py`).
"""

from __future__ import annotations

import threading
from collections import OrderedDict

from trajcache.geometry.collision.bodies import RobotGeometry, SceneGeometry
from trajcache.geometry.collision.free_pairs import proven_free_pairs
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.scene import Scene

_CACHE_SIZE = 64


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
    built.drop_pairs(proven_free_pairs(built))
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
