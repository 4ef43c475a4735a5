"""Parsed scenes of the service process, by content hash: each scene version is parsed once."""

from __future__ import annotations

from trajcache.core.lru import LRU
from trajcache.geometry.scene.scene import Scene

__all__ = ["SceneCache"]


class SceneCache:
    """Parsed scenes keyed by scene hash (each version is parsed once), least recent evicted."""

    def __init__(self, capacity: int = 256) -> None:
        self.capacity = capacity
        self._scenes: LRU[str, Scene] = LRU(capacity=capacity)

    def get(self, scene_hash: str) -> Scene | None:
        """The cached scene with this hash, or None."""
        return self._scenes.get(scene_hash)

    def put(self, scene: Scene) -> Scene:
        """Cache `scene` under its hash and return it."""
        return self._scenes.put(scene.hash, scene)

    def clear(self) -> None:
        """Forget every scene."""
        self._scenes.clear()

    def __len__(self) -> int:
        return len(self._scenes)
