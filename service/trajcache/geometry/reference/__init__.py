"""The reference setup shipped with trajcache: an xArm7-like mobile manipulator and a restroom."""

from __future__ import annotations

from trajcache.geometry.reference.restroom import (
    RESTROOM_LAYOUT,
    STALL_FRONTS,
    STATIONS,
    BaseStation,
    RestroomLayout,
    StallFront,
    restroom_layout,
    restroom_scene,
)
from trajcache.geometry.reference.robot import (
    REFERENCE_BASE,
    REFERENCE_NAME,
    STOWED_ARM,
    reference_model,
    reference_urdf,
)

__all__ = [
    "REFERENCE_BASE",
    "REFERENCE_NAME",
    "RESTROOM_LAYOUT",
    "STALL_FRONTS",
    "STATIONS",
    "STOWED_ARM",
    "BaseStation",
    "RestroomLayout",
    "StallFront",
    "reference_model",
    "reference_urdf",
    "restroom_layout",
    "restroom_scene",
]
