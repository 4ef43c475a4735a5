"""A path's quality: path lengths, clearance to the scene, motion bounds; pure geometry.

Cheap metrics (state-space and end-effector path length, tens of microseconds) are computed for
every answer; clearance (FCL distances) costs milliseconds and is computed when a trajectory is
stored (`services.quality`, which also times trajectories), or when a request asks for it
(`services.bookkeeping.answer_quality`).

Clearance is the smallest FCL distance between a robot collision element and a scene object over
states sampled along the trajectory (at the validator's resolution). It is found by branch and
bound: a bounding-sphere-to-box lower bound on every (state, element, object) distance orders the
pairs, and FCL runs only until the next lower bound exceeds the best distance found.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Any

import fcl
import numba
import numpy as np

from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.model.kernels import forward_kinematics_kernel
from trajcache.geometry.model.kinematics import fk_tables, link_motion_bounds
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import compiled_input, segment_deltas
from trajcache.geometry.validation.validator import Resolution, interpolate

MAX_DISTANCE_QUERIES = 20_000  # FCL calls per clearance; beyond it the result is an upper bound


@dataclass(frozen=True)
class MinClearance:
    """The smallest distance to the scene, where it occurs, and whether it is exact."""

    distance: float  # m; 0 when touching
    link: str
    object: str
    state_index: int  # index into the sampled states
    exact: bool = True  # False when MAX_DISTANCE_QUERIES cut the search short


@dataclass(frozen=True)
class Quality:
    """Quality of one trajectory; None where a metric was not computed (or has no value)."""

    path_length: float  # Σ‖Δstate‖ (state units, base angle the short way)
    ee_path_length: float  # m, travelled by the end-effector link's origin
    min_clearance: float | None = None  # m; None: not computed, or no obstacle in the scene
    duration_s: float | None = None  # after time-optimal timing

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "path_length": self.path_length,
            "ee_path_length": self.ee_path_length,
            "min_clearance": self.min_clearance,
            "duration_s": self.duration_s,
        }


_EE_LINKS: weakref.WeakKeyDictionary[RobotModel, int] = weakref.WeakKeyDictionary()


def end_effector_link(model: RobotModel) -> int:
    """Index of the end-effector link: the configured one, or the tip of the longest chain."""
    cached = _EE_LINKS.get(model)
    if cached is not None:
        return cached
    if model.end_effector_link is not None:
        if model.end_effector_link not in model.link_names:
            raise ValueError(f"end-effector link {model.end_effector_link!r} is not in the model")
        link = model.link_names.index(model.end_effector_link)
    else:
        depth = {0: 0}
        for joint in model.joints:  # topological order: parents first
            depth[joint.child] = depth[joint.parent] + 1
        # deepest link; among equals the one listed last (the tool, not a side branch)
        link = max(depth, key=lambda k: (depth[k], k))
    _EE_LINKS[model] = link
    return link


def ee_path_length(
    model: RobotModel, states: FloatArray, *, step: float = 0.05, max_samples: int = 16
) -> float:
    """Length of the end-effector's path (m), sampled every `step` along the trajectory.

    Samples are spaced at most `step` in every state value (rad or m), but no more than
    `max_samples` in all (a chord sum; shorter than the true curve by a fraction of a percent).
    Compiled (`_ee_length_kernel`): it runs for every answer.
    """
    array = compiled_input(states)
    if len(array) < 2:
        return 0.0
    deltas = compiled_input(segment_deltas(array, base=model.base))
    link, n_links = end_effector_link(model), len(model.link_names)
    fk = fk_tables(model)
    return float(_ee_length_kernel(array, deltas, step, max_samples, link, n_links, fk))


@numba.njit(cache=True, nogil=True)
def _ee_length_kernel(states, deltas, step, max_samples, link, n_links, fk):  # type: ignore[no-untyped-def]  # pragma: no cover
    """`ee_path_length`: segment k gets max(⌈steps_k · scale⌉, 1) samples, its start first,
    where steps_k = max |Δ_k| / step and scale = min(1, max_samples / Σ steps); then the last
    state; the chord sum of link `link`'s origin over them (`fk`: `fk_tables`)."""
    n_seg, dof = deltas.shape
    steps = np.empty(n_seg)
    for k in range(n_seg):
        widest = 0.0
        for d in range(dof):
            widest = max(widest, abs(deltas[k, d]))
        steps[k] = widest / step
    total = steps.sum()
    scale = min(1.0, max_samples / total) if total > 0.0 else 1.0
    counts = np.maximum(np.ceil(steps * scale), 1.0).astype(np.int64)
    dense = np.empty((counts.sum() + 1, dof))
    n = 0
    for k in range(n_seg):
        for j in range(counts[k]):
            dense[n] = states[k] + (j / counts[k]) * deltas[k]
            n += 1
    dense[n] = states[n_seg]
    tf = np.empty((dense.shape[0], n_links, 4, 4))
    forward_kinematics_kernel(
        dense, fk[0], fk[1], fk[2], fk[3], fk[4], fk[5], fk[6], fk[7], fk[8], fk[9], fk[10], tf
    )
    length = 0.0
    for i in range(1, dense.shape[0]):
        length += math.sqrt(
            (tf[i, link, 0, 3] - tf[i - 1, link, 0, 3]) ** 2
            + (tf[i, link, 1, 3] - tf[i - 1, link, 1, 3]) ** 2
            + (tf[i, link, 2, 3] - tf[i - 1, link, 2, 3]) ** 2
        )
    return length


def min_clearance(
    checker: CollisionChecker, states: FloatArray, *, resolution: Resolution | None = None
) -> MinClearance | None:
    """Smallest distance between the robot and the scene along `states`; None without obstacles.

    States are sampled along the straight segments at `resolution` (the validator's default).
    """
    scene = checker.scene
    if not scene.objects:
        return None
    samples = interpolate(
        np.asarray(states, dtype=float), checker.model, resolution or Resolution()
    )
    poses = checker.element_poses(samples)  # (N, E, 4, 4)
    n, e = poses.shape[:2]
    centers = poses[:, :, :3, 3].reshape(-1, 3)
    # Lower bound per (state, element, object): sphere around the element vs the object's box
    # (object frame: Rᵀ(c − t), all objects in one matmul as in the collision checker).
    local = (centers @ scene.rotation_cat).reshape(n, e, -1, 3) - scene.offset
    outside = np.maximum(np.abs(local) - scene.half, 0.0)
    bound = np.sqrt(np.sum(outside**2, axis=-1)) - checker.robot.radius[None, :, None]
    flat = bound.ravel()
    objects = checker.robot.objects()
    request = fcl.DistanceRequest()

    def distance(pair: int) -> float:
        s, k, m = np.unravel_index(pair, bound.shape)
        pose = poses[s, k]
        objects[k].setTranslation(pose[:3, 3])
        objects[k].setRotation(pose[:3, :3])
        found = fcl.distance(objects[k], scene.objects[m], request, fcl.DistanceResult())
        return max(float(found), 0.0)

    first = int(np.argmin(flat))
    best, where = distance(first), first
    queries = 1
    # Only pairs whose lower bound beats the first distance can hold the minimum.
    candidates = np.flatnonzero(flat < best)
    for pair in candidates[np.argsort(flat[candidates], kind="stable")].tolist():
        if flat[pair] >= best or best == 0.0 or queries >= MAX_DISTANCE_QUERIES:
            break
        if pair == first:
            continue
        found = distance(pair)
        queries += 1
        if found < best:
            best, where = found, pair
    exact = queries < MAX_DISTANCE_QUERIES or best == 0.0
    state, element, obj = (int(v) for v in np.unravel_index(where, bound.shape))
    link = checker.model.link_names[int(checker.robot.element_link[element])]
    return MinClearance(best, link, scene.ids[obj], state, exact)


_MOTION_BOUNDS: weakref.WeakKeyDictionary[RobotModel, FloatArray] = weakref.WeakKeyDictionary()


def motion_bound(model: RobotModel) -> FloatArray:
    """Largest displacement of any point of the robot per unit change of each state value."""
    cached = _MOTION_BOUNDS.get(model)
    if cached is None:
        cached = link_motion_bounds(model).max(axis=0)
        _MOTION_BOUNDS[model] = cached
    return cached
