"""Cached trajectory ends near a pose target, read from the end-pose index.

The target's link is looked up through its anchor (`geometry.model.end_poses`): the anchor's
target is `T_goal · offset⁻¹`, relative to the root link where the base stands
(`base_state`). An anchor the model does not index has no cached ends (IK starts from the
seed and restarts instead).

- `ends_within`: ends whose link is within the target's tolerances. The index is searched
  around the anchor's target with the position tolerance widened by |offset| times the
  orientation tolerance: if the link is within the tolerances, its anchor is within that
  radius (an orientation error δ moves the link by at most δ·|offset| more than its anchor)
  and the two orientation errors are equal. Each end found is then checked exactly, by
  forward kinematics of the link on the model as the robot holds its joints; the index only
  narrows the search and never decides.
- `nearest_starts`: the ends whose link lies nearest the target's position (IK starts): the
  ends nearest by the anchor within the first of the widening radii that holds enough of them
  (a shortlist), ranked by the link's own position by forward kinematics. A start that misses
  the target helps too: when IK from the nearest end lands in collision, the next one seeds it.
"""

from __future__ import annotations

import math

import numpy as np
from sqlalchemy.orm import Session

from trajcache.geometry.model.end_poses import anchor_of, anchor_offset
from trajcache.geometry.model.ik import PoseTarget
from trajcache.geometry.model.kinematics import forward_kinematics
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.services.catalog.end_poses import EndsNear, ends_near, index_links

__all__ = ["AS_IS_POOL", "CACHED_STARTS", "ends_within", "nearest_starts"]

CACHED_STARTS = 3  # cached end states tried as IK starts after the seed
AS_IS_POOL = 64  # the most ends within the tolerances read for one pose goal
# m: IK starts are looked for ever wider (the search reads every indexed end in a slab of twice
# the radius, so the first radius is small; the last reads them all, where the cache is sparse)
_SEARCH_RADII = (0.03, 0.1, 0.3, math.inf)
_FEW = 2_000  # trajectories whose ends one scan of the index reads faster than several searches
_SHORTLIST = 4 * CACHED_STARTS  # ends nearest by the anchor, ranked again by the link itself
_NONE = EndsNear(np.empty((0, 0)), np.empty((0, 0)), np.empty(0))


def ends_within(
    session: Session, model: RobotModel, checked: RobotModel, target: PoseTarget, base: FloatArray
) -> EndsNear:
    """The cached ends (of `model`'s trajectories) at which the target's link is within its
    tolerances on `checked`, the base at `base`'s, nearest first."""
    found = _anchor_target(session, model, checked, target, base)
    if found is None:
        return _NONE
    anchor, pose, reach = found
    widened = target.position_tolerance + reach * target.orientation_tolerance
    ends = ends_near(
        session,
        model.model_id,
        anchor,
        pose,
        radius=widened,
        orientation_tolerance=target.orientation_tolerance,
        limit=AS_IS_POOL,
    )
    if len(ends.gaps) == 0:
        return ends
    states = _on_base(checked, ends.states, base)
    frames = forward_kinematics(checked, states)[:, checked.link_names.index(target.link)]
    gap = np.linalg.norm(frames[:, :3, 3] - target.pose[:3, 3], axis=1)
    turn = np.einsum("nij,ij->n", frames[:, :3, :3], target.pose[:3, :3])  # trace(Rᵀ R*)
    angle = np.arccos(np.clip((turn - 1.0) / 2.0, -1.0, 1.0))
    keep = (gap <= target.position_tolerance) & (angle <= target.orientation_tolerance)
    return EndsNear(states[keep], ends.partners[keep], gap[keep])


def nearest_starts(
    session: Session,
    model: RobotModel,
    checked: RobotModel,
    target: PoseTarget,
    base: FloatArray,
    *,
    stored: int,
) -> list[FloatArray]:
    """The CACHED_STARTS cached end states whose link lies nearest the target's position (the
    base at `base`'s), among the `stored` trajectories of the model."""
    found = _anchor_target(session, model, checked, target, base)
    if found is None:
        return []
    anchor, pose, _ = found
    ends = _NONE
    radii = _SEARCH_RADII if stored > _FEW else _SEARCH_RADII[-1:]
    for radius in radii:  # the anchor's nearest: the link's if oriented as asked
        ends = ends_near(session, model.model_id, anchor, pose, radius=radius, limit=_SHORTLIST)
        if len(ends.gaps) >= CACHED_STARTS:
            break
    states = _on_base(checked, ends.states, base)
    if len(states) == 0:
        return []
    links = forward_kinematics(checked, states)[:, checked.link_names.index(target.link), :3, 3]
    nearest = np.argsort(np.linalg.norm(links - target.pose[:3, 3], axis=1), kind="stable")
    return list(states[nearest[:CACHED_STARTS]])


def _anchor_target(
    session: Session, model: RobotModel, checked: RobotModel, target: PoseTarget, base: FloatArray
) -> tuple[str, FloatArray, float] | None:
    """The indexed anchor of the target's link, its target relative to the root link, and
    the length of the link's offset from it; None when the anchor is not indexed."""
    link = checked.link_names.index(target.link)
    anchor = anchor_of(checked, link)
    if checked.link_names[anchor] not in index_links(session, model):
        return None
    offset = anchor_offset(checked, link, anchor)
    root = forward_kinematics(checked, np.asarray(base, dtype=float)[None, :])[0, 0]
    pose = np.linalg.inv(root) @ target.pose @ np.linalg.inv(offset)
    return checked.link_names[anchor], pose, float(np.linalg.norm(offset[:3, 3]))


def _on_base(model: RobotModel, states: FloatArray, base: FloatArray) -> FloatArray:
    """`states` with the base pose of `base` (a planar base's cached ends stood elsewhere)."""
    out = np.array(states, dtype=float).reshape(-1, model.dof)
    out[:, : model.arm_offset] = np.asarray(base)[: model.arm_offset]
    return out
