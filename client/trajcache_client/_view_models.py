"""Typed bodies of the 3D view's endpoints: model geometry, stored scenes, paths as link poses."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from trajcache_client._models import PlanEvent, RejectedCandidate, _Answer

__all__ = [
    "Failure",
    "Frames",
    "ModelElement",
    "ModelView",
    "PathView",
    "StoredScene",
]


class ModelElement(_Answer):
    """A collision element on link `link`, posed there by `origin` (x, y, z, qx, qy, qz, qw).

    A primitive has its `size` (box: full extents; sphere: radius; cylinder and capsule: radius
    and length along local z); a mesh has `mesh`, the path of its triangles as binary STL.
    """

    link: int
    origin: list[float]
    kind: Literal["box", "sphere", "cylinder", "capsule", "mesh"] | str
    size: list[float]
    mesh: str | None
    triangles: int | None


class ModelView(_Answer):
    """A model's links and their collision geometry, as the 3D view draws them."""

    model_id: str
    name: str
    base: Literal["fixed", "planar"] | str
    state_names: list[str]
    link_names: list[str]
    end_effector_link: int
    elements: list[ModelElement]


class StoredScene(_Answer):
    """A stored scene in native form: a robot's version (`robot_id`, `version`), a seed job's
    scene (`seed_job_id`), or the empty scene (none of them)."""

    robot_id: str | None
    version: int | None
    hash: str
    created_at: datetime | None
    objects: list[dict[str, Any]]
    env: dict[str, float]
    allowed_collisions: list[list[str]]
    attached_objects: list[dict[str, Any]]
    seed_job_id: int | None = None


class Frames(_Answer):
    """A path's frames: one per validation sample, each with the world poses of the posed
    `links`, 7 numbers per link (x, y, z, qx, qy, qz, qw)."""

    count: int
    samples: int
    sample: list[int]
    key: list[int]
    links: list[int]
    states: list[list[float]]
    poses: list[list[float]]


class Failure(_Answer):
    """Where a rejected candidate failed: its frame, the posed links at the failing state and
    the plan event's record of it."""

    candidate: int
    frame: int
    poses: list[float]
    rejection: RejectedCandidate


class GoalPose(_Answer):
    """A plan request's goal given as a link's pose: position (x, y, z) and quaternion
    (x, y, z, w), in the model's base frame (the world for a planar base)."""

    link: str
    position: list[float]
    orientation: list[float]
    position_tolerance: float
    orientation_tolerance: float


class CartesianLines(_Answer):
    """The straight lines a Cartesian path's link follows: its pose at the start, then each
    waypoint (x, y, z, qx, qy, qz, qw)."""

    link: str
    poses: list[list[float]]


class PathView(_Answer):
    """A path to draw: its model, scene, frames, and where it failed if it did; a pose goal
    and a Cartesian path's lines when there are any."""

    model_id: str
    state_names: list[str]
    trajectory_id: int | None
    scene_hash: str | None
    scene: StoredScene | None
    key_states: list[list[float]]
    frames: Frames
    failure: Failure | None
    event: PlanEvent | None
    notes: list[str]
    goal_pose: GoalPose | None = None
    cartesian: CartesianLines | None = None
