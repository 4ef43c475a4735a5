"""The frames a MoveIt scene's world objects may be given in, and their poses in the world.

World frames (`""`, `world`, `map`, `odom`) are the world itself. A robot's root link, and every
link rigidly fixed to it through fixed joints, is a frame MoveIt resolves through the robot's
state: for a fixed base the root link is the world frame (identity; MoveIt's virtual joint is
fixed), so such a link's world pose is its pose in the root frame, the product of its fixed
joints' origins. For a planar base the root link moves with the base, and a scene does not say
where the base is, so such frames are refused with a message saying so rather than guessed.
Other frames (a moving link, a TF frame) are refused.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray

WORLD_FRAMES = frozenset({"", "world", "map", "odom"})


@dataclass(frozen=True)
class SceneFrames:
    """Robot frames besides the world frames: world poses of links fixed to the root of a fixed
    base, or (`moving`) the names of such links of a planar base, which are refused."""

    poses: Mapping[str, FloatArray] = field(default_factory=dict)
    moving: frozenset[str] = frozenset()


NO_FRAMES = SceneFrames()


def root_frames(model: RobotModel) -> SceneFrames:
    """The root link and the links fixed to it (fixed joints only), posed in the root frame."""
    poses: dict[str, FloatArray] = {model.link_names[0]: np.eye(4)}
    for joint in model.joints:  # parents before children
        parent = model.link_names[joint.parent]
        if joint.kind == "fixed" and parent in poses:
            poses[model.link_names[joint.child]] = poses[parent] @ joint.origin
    if model.base is BaseType.PLANAR:
        return SceneFrames(moving=frozenset(poses))
    return SceneFrames(poses=poses)


def object_frame(
    obj: Mapping[str, Any], oid: str, link: str | None = None, frames: SceneFrames = NO_FRAMES
) -> FloatArray:
    """The world pose of a CollisionObject's `header.frame_id` (an attached object: its link's
    own frame, the identity); SceneError for a frame that cannot be resolved."""
    header = obj.get("header") or {}
    if not isinstance(header, Mapping):
        raise SceneError(f"object {oid!r}: header must be a mapping")
    given = header.get("frame_id", "")
    frame = given.lstrip("/") if isinstance(given, str) else given
    if link is not None:
        if frame not in ("", link):
            raise SceneError(
                f"attached object {oid!r}: header.frame_id {given!r} is not its link "
                f"{link!r}; give its pose in the frame of the link that carries it"
            )
        return np.eye(4)
    if frame in WORLD_FRAMES:
        return np.eye(4)
    if isinstance(frame, str) and frame in frames.poses:
        return np.asarray(frames.poses[frame], dtype=float)
    if frame in frames.moving:
        raise SceneError(
            f"object {oid!r}: header.frame_id {given!r} is a link of the robot's planar base, "
            "which moves: a scene cannot say where it is; give the object in a world frame"
        )
    robot = f" or the robot's root-fixed links {sorted(frames.poses)}" if frames.poses else ""
    raise SceneError(
        f"object {oid!r}: header.frame_id {given!r} is not a world frame "
        f"(only {sorted(WORLD_FRAMES)}{robot} are supported)"
    )
