"""The limits every stored or planned-in scene is held to: how many objects, and how far out.

A scene's numbers are finite by parsing; these limits keep them in the range where the collision
checks are exact: a box a kilometre long and one 1e300 m long would otherwise both be accepted,
and the second is beyond what the bounds' arithmetic can represent.
"""

from __future__ import annotations

from dataclasses import dataclass

from trajcache.core.config import Settings
from trajcache.geometry.scene.scene import Scene, farthest_object
from trajcache.services.errors import InvalidInputError, PayloadTooLargeError


@dataclass(frozen=True)
class SceneLimits:
    """Most objects in a scene, and how far (m) any object may reach from its frame's origin."""

    max_objects: int
    max_extent_m: float

    @classmethod
    def of(cls, settings: Settings) -> SceneLimits:
        """The limits the settings give (`max_scene_objects`, `max_scene_extent_m`)."""
        return cls(settings.max_scene_objects, settings.max_scene_extent_m)


def check_scene(scene: Scene, limits: SceneLimits, where: str = "scene") -> None:
    """PayloadTooLargeError for too many objects; InvalidInputError for one reaching too far."""
    if len(scene.objects) > limits.max_objects:
        raise PayloadTooLargeError(
            f"{where} has {len(scene.objects)} objects, more than "
            f"max_scene_objects={limits.max_objects}"
        )
    farthest = farthest_object(scene)
    if farthest is not None and farthest[1] > limits.max_extent_m:
        obj, reach = farthest
        raise InvalidInputError(
            f"{where}: object {obj.id!r} reaches {reach:.4g} m from the origin of its frame, "
            f"beyond max_scene_extent_m={limits.max_extent_m:g}"
        )
