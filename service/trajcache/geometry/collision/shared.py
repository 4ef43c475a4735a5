"""The shared geometry of a model and of a scene: built once, cached, and shared read-only.

A model's `RobotGeometry` leaves out the self-collision pairs proven free within the joint limits
(`free_pairs.py`); the proof poses the geometry through the distance bounds and narrow phase,
which is why it is applied here, above them, and not where the geometry is built (`bodies.py`).
"""

from __future__ import annotations

from trajcache.core.lru import LRU
from trajcache.geometry.collision.bodies import RobotGeometry, SceneGeometry
from trajcache.geometry.collision.free_pairs import proven_free_pairs
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.scene import Scene

CACHE_SIZE = 64


class GeometryCache:
    """The RobotGeometry of each model (by id) and SceneGeometry of each scene (by hash)."""

    def __init__(self, capacity: int = CACHE_SIZE) -> None:
        self.robots: LRU[str, RobotGeometry] = LRU(capacity=capacity)
        self.scenes: LRU[str, SceneGeometry] = LRU(capacity=capacity)

    def robot(self, model: RobotModel) -> RobotGeometry:
        """The shared RobotGeometry of a model (built once per model id)."""
        cached = self.robots.get(model.model_id)
        if cached is not None and cached.model is model:
            return cached
        return self.robots.put(model.model_id, _build_robot(model))

    def scene(self, scene: Scene) -> SceneGeometry:
        """The shared SceneGeometry of a scene version (built once per content hash)."""
        key = scene.hash or f"id:{id(scene)}"
        return self.scenes.get_or_build(key, lambda: SceneGeometry(scene))

    def clear(self) -> None:
        """Forget every geometry."""
        self.robots.clear()
        self.scenes.clear()


def _build_robot(model: RobotModel) -> RobotGeometry:
    built = RobotGeometry(model)
    built.drop_pairs(proven_free_pairs(built))
    return built


# The geometry of checkers built without a cache of their own: planners, which run in worker
# processes (each has its own), and tools. The service's validators use its context's cache.
PROCESS_GEOMETRY = GeometryCache()


def robot_geometry(model: RobotModel, cache: GeometryCache | None = None) -> RobotGeometry:
    """The shared RobotGeometry of a model (cached by model id)."""
    return (cache or PROCESS_GEOMETRY).robot(model)


def scene_geometry(scene: Scene, cache: GeometryCache | None = None) -> SceneGeometry:
    """The shared SceneGeometry of a scene version (cached by content hash)."""
    return (cache or PROCESS_GEOMETRY).scene(scene)
