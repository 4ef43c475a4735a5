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
- `pose_ends`: both, for a pose goal, from `nearest_starts`' shortlist as its search reads it
  (the `_SHORTLIST` ends nearest the anchor's target within the first radius that holds enough,
  whatever their orientation). When that radius is at least the widened one, those of them
  within the widened radius are every end `ends_within` would read, unless all of them are
  within it (more may be); otherwise `ends_within`'s own oriented search runs.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from sqlalchemy.orm import Session

from trajcache.geometry.model.end_poses import anchor_of, anchor_offset
from trajcache.geometry.model.ik import PoseTarget
from trajcache.geometry.model.kinematics import forward_kinematics
from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.services.catalog.end_poses import EndsNear, ends_near, index_links
from trajcache.services.catalog.index_store import IndexStore

__all__ = [
    "AS_IS_POOL",
    "CACHED_STARTS",
    "PoseEnds",
    "ends_within",
    "meets_target",
    "nearest_starts",
    "pose_ends",
    "stored_count",
]

CACHED_STARTS = 3  # cached end states tried as IK starts after the seed
AS_IS_POOL = 64  # the most ends within the tolerances read for one pose goal
# m: IK starts are looked for ever wider (the search reads every indexed end in a slab of twice
# the radius, so the first radius is small; the last reads them all, where the cache is sparse)
_SEARCH_RADII = (0.03, 0.1, 0.3, math.inf)
# trajectories up to which the shortlist is one scan of every end rather than a search by radii
# (up to four queries where the cache is sparse). Measured above it: MBM pose goals, 700
# problems, about 1,400 trajectories, finding the goal state 2.28 ms by one scan, 1.63 ms by
# radii. The 200 itself is not measured.
_FEW = 200
_SHORTLIST = 4 * CACHED_STARTS  # ends nearest by the anchor, ranked again by the link itself
_NONE = EndsNear(np.empty((0, 0)), np.empty((0, 0)), np.empty(0))
_FRAMES: weakref.WeakKeyDictionary[
    RobotModel, dict[str, tuple[int, FloatArray, float, FloatArray | None]]
] = weakref.WeakKeyDictionary()


def stored_count(indexes: IndexStore, session: Session, model: RobotModel) -> int:
    """How many trajectories of `model` this replica's index held at its last sync: no sync
    query for it (an estimate, for choosing how to search: `stored` below)."""
    known = indexes.sizes().get(model.model_id)
    return len(indexes.index(session, model)) if known is None else known


def ends_within(
    session: Session, model: RobotModel, checked: RobotModel, target: PoseTarget, base: FloatArray
) -> EndsNear:
    """The cached ends (of `model`'s trajectories) at which the target's link is within its
    tolerances on `checked`, the base at `base`'s, nearest first."""
    found = _anchor_target(session, model, checked, target, base)
    if found is None:
        return _NONE
    return _within(session, model, checked, target, base, found)


def _within(
    session: Session,
    model: RobotModel,
    checked: RobotModel,
    target: PoseTarget,
    base: FloatArray,
    found: tuple[str, FloatArray, float],
    ends: EndsNear | None = None,
) -> EndsNear:
    """`ends_within` from the anchor's target; `ends`: the index rows read already, when they
    hold every end within the widened radius."""
    anchor, pose, reach = found
    widened = target.position_tolerance + reach * target.orientation_tolerance
    if ends is None:
        ends = ends_near(
            session,
            model.model_id,
            anchor,
            pose,
            radius=widened,
            orientation_tolerance=target.orientation_tolerance,
            limit=AS_IS_POOL,
        )
    else:
        ends = _first(ends, int(np.searchsorted(ends.gaps, widened, side="right")))
    if len(ends.gaps) == 0:
        return ends
    states = _on_base(checked, ends.states, base)
    keep, gap = meets_target(checked, target, states)
    return EndsNear(states[keep], ends.partners[keep], gap[keep])


def meets_target(
    checked: RobotModel, target: PoseTarget, states: FloatArray
) -> tuple[npt.NDArray[np.bool_], FloatArray]:
    """Which of `states` put the target's link within its tolerances (forward kinematics on
    `checked`), and the link's distance from the target's position at each."""
    frames = forward_kinematics(checked, states)[:, checked.link_names.index(target.link)]
    gap = np.linalg.norm(frames[:, :3, 3] - target.pose[:3, 3], axis=1)
    turn = np.einsum("nij,ij->n", frames[:, :3, :3], target.pose[:3, :3])  # trace(Rᵀ R*)
    angle = np.arccos(np.clip((turn - 1.0) / 2.0, -1.0, 1.0))
    return (gap <= target.position_tolerance) & (angle <= target.orientation_tolerance), gap


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
    ends, _ = _shortlist(session, model, found, stored)
    return _ranked_starts(checked, target, base, ends)


@dataclass(frozen=True)
class PoseEnds:
    """What a pose goal reads of the cache: the ends within its tolerances (`ends_within`)
    and the IK starts (`nearest_starts`)."""

    within: EndsNear
    starts: list[FloatArray]


def pose_ends(
    session: Session,
    model: RobotModel,
    checked: RobotModel,
    target: PoseTarget,
    base: FloatArray,
    *,
    stored: int,
) -> PoseEnds:
    """`ends_within` and `nearest_starts` at once, from the shortlist's read (module
    docstring)."""
    found = _anchor_target(session, model, checked, target, base)
    if found is None:
        return PoseEnds(_NONE, [])
    ends, radius = _shortlist(session, model, found, stored)
    reach = found[2]  # the link's offset from its anchor
    widened = target.position_tolerance + reach * target.orientation_tolerance
    full = len(ends.gaps) == _SHORTLIST and ends.gaps[-1] <= widened  # more may lie within
    complete = radius >= widened and not full  # every end within the widened radius is read
    within = _within(session, model, checked, target, base, found, ends if complete else None)
    return PoseEnds(within, _ranked_starts(checked, target, base, ends))


def _shortlist(
    session: Session, model: RobotModel, found: tuple[str, FloatArray, float], stored: int
) -> tuple[EndsNear, float]:
    """The `_SHORTLIST` ends nearest the anchor's target (`_anchor_target`), whatever their
    orientation, within the first search radius that holds CACHED_STARTS of them (one unbounded
    scan while `stored` is at most `_FEW`), and that radius."""
    anchor, pose, _ = found
    ends, radius = _NONE, 0.0
    for radius in _SEARCH_RADII if stored > _FEW else _SEARCH_RADII[-1:]:
        ends = ends_near(session, model.model_id, anchor, pose, radius=radius, limit=_SHORTLIST)
        if len(ends.gaps) >= CACHED_STARTS:
            break
    return ends, radius


def _ranked_starts(
    checked: RobotModel, target: PoseTarget, base: FloatArray, ends: EndsNear
) -> list[FloatArray]:
    """The CACHED_STARTS of `ends` whose link lies nearest the target's position."""
    states = _on_base(checked, ends.states, base)
    if len(states) == 0:
        return []
    links = forward_kinematics(checked, states)[:, checked.link_names.index(target.link), :3, 3]
    nearest = np.argsort(np.linalg.norm(links - target.pose[:3, 3], axis=1), kind="stable")
    return list(states[nearest[:CACHED_STARTS]])


def _first(ends: EndsNear, n: int) -> EndsNear:
    """The `n` nearest of `ends`."""
    return EndsNear(ends.states[:n], ends.partners[:n], ends.gaps[:n])


def _anchor_target(
    session: Session, model: RobotModel, checked: RobotModel, target: PoseTarget, base: FloatArray
) -> tuple[str, FloatArray, float] | None:
    """The indexed anchor of the target's link, its target relative to the root link, and
    the length of the link's offset from it; None when the anchor is not indexed."""
    anchor, inverse_offset, reach, fixed_root = _anchor_frames(checked, target.link)
    if checked.link_names[anchor] not in index_links(session, model):
        return None
    if fixed_root is None:  # a planar base: the root link stands where the base does
        fixed_root = np.linalg.inv(
            forward_kinematics(checked, np.asarray(base, dtype=float)[None, :])[0, 0]
        )
    return checked.link_names[anchor], fixed_root @ target.pose @ inverse_offset, reach


def _anchor_frames(
    checked: RobotModel, link_name: str
) -> tuple[int, FloatArray, float, FloatArray | None]:
    """The link's anchor, the inverse of its offset from it, the offset's length, and the
    inverse of the root link's pose when no state value moves it (a fixed base), else None:
    constants of the model, computed once per loaded model and link."""
    frames = _FRAMES.setdefault(checked, {})
    known = frames.get(link_name)
    if known is not None:
        return known
    link = checked.link_names.index(link_name)
    anchor = anchor_of(checked, link)
    offset = anchor_offset(checked, link, anchor)
    root: FloatArray | None = None
    if checked.base is not BaseType.PLANAR:
        zero = np.clip(np.zeros((1, checked.dof)), checked.lower, checked.upper)
        root = np.asarray(np.linalg.inv(forward_kinematics(checked, zero)[0, 0]), dtype=float)
    inverse = np.asarray(np.linalg.inv(offset), dtype=float)
    found = (anchor, inverse, float(np.linalg.norm(offset[:3, 3])), root)
    frames[link_name] = found
    return found


def _on_base(model: RobotModel, states: FloatArray, base: FloatArray) -> FloatArray:
    """`states` with the base pose of `base` (a planar base's cached ends stood elsewhere)."""
    out = np.array(states, dtype=float).reshape(-1, model.dof)
    out[:, : model.arm_offset] = np.asarray(base)[: model.arm_offset]
    return out
