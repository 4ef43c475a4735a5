"""The links whose poses a trajectory's ends are indexed by, and those poses.

A pose goal names a link: one of the model's tips (its end-effector link, an SRDF end
effector's parent link, an SRDF chain's tip) or any other. A link's *anchor* is the nearest
link at or above it whose pose the state moves: walking up, every joint passed is fixed or
held (not driven by a state value), so the link is rigidly attached to its anchor and
`T_link = T_anchor · offset` with one constant offset for every state (of a model as it holds
its joints). So the index keeps the poses of the tips' anchors only, and a goal on any link
with an indexed anchor (`panda_hand` fixed on `panda_link8`) is looked up as the anchor's pose
`T_goal · offset⁻¹`. Rotations are rigid too: the angle between the link's orientation and
the goal's equals the anchor's.

Poses are relative to the root link (the base frame of a planar base), so a mobile base's
cached ends are found wherever the base stood.
"""

from __future__ import annotations

import numpy as np

from trajcache.geometry.model.kinematics import forward_kinematics
from trajcache.geometry.model.poses import pose7
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.srdf import parse_srdf
from trajcache.geometry.path_quality import end_effector_link

__all__ = ["anchor_of", "anchor_offset", "indexed_anchors", "root_relative", "tip_links"]


def tip_links(model: RobotModel, srdf: str | None) -> tuple[str, ...]:
    """The links pose goals name: the end-effector link, then the SRDF's end effectors' parent
    links and its chains' tips (those the model has), without repeats."""
    names = [model.link_names[end_effector_link(model)]]
    if srdf:
        parsed = parse_srdf(srdf)
        names += list(parsed.end_effectors.values())
        names += [tip for group in parsed.groups.values() for _, tip in group.chains]
    return tuple(dict.fromkeys(n for n in names if n in model.link_names))


def anchor_of(model: RobotModel, link: int) -> int:
    """The nearest link at or above `link` moved by a state value (0, the root, if none)."""
    parent_joint = {joint.child: joint for joint in model.joints}
    while link in parent_joint:
        joint = parent_joint[link]
        if joint.kind != "fixed" and joint.index >= 0:
            return link
        link = joint.parent
    return link


def indexed_anchors(model: RobotModel, srdf: str | None) -> tuple[str, ...]:
    """The anchors of the tip links that a state moves (sorted names): the links indexed."""
    anchors = {anchor_of(model, model.link_names.index(tip)) for tip in tip_links(model, srdf)}
    return tuple(sorted(model.link_names[a] for a in anchors if a != 0))


def root_relative(model: RobotModel, states: FloatArray, links: list[int]) -> FloatArray:
    """Poses (N, K, 7) of `links` relative to the root link at each of the (N, D) states."""
    tf = forward_kinematics(model, np.ascontiguousarray(states, dtype=float))
    relative = np.linalg.inv(tf[:, :1]) @ tf[:, links]
    return pose7(relative)


def anchor_offset(model: RobotModel, link: int, anchor: int) -> FloatArray:
    """The constant transform from `anchor`'s frame to `link`'s (rigidly attached)."""
    state = np.clip(np.zeros((1, model.dof)), model.lower, model.upper)
    tf = forward_kinematics(model, state)[0]
    return np.asarray(np.linalg.inv(tf[anchor]) @ tf[link], dtype=float)
