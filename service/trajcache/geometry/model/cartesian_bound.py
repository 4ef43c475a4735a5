"""How far a link's origin may leave a straight Cartesian line between two joint samples.

A Cartesian path is a list of joint states, each putting the link's origin near a point of a
straight line; between two of them the robot moves straight in joint space, s(t) = a + t·Δ for
t ∈ [0, 1], and the origin p(t) follows a curve, not the line. The bound:

    dist(p(t), line) ≤ (3·W²·ρ + 3·W·S) / 8 + max(dist(p(0), line), dist(p(1), line))

where W = Σ |Δ| over the revolute (and continuous) joints of the link's chain, S = Σ |Δ| over
its prismatic joints (a mimic joint's change is its multiplier times its leader's), and ρ
bounds the distance between any two points of the chain from its first moving joint to the
link's origin: the sum of the joint origin offsets after that joint, plus each prismatic
joint's largest extent (`kinematics.prismatic_extent`). A planar base holds still (a Cartesian
path moves the arm only).

Proof. Write o_i for joint i's origin (a point of its axis) and u_i for its unit axis, both in
the world and moving with the joints before it. Along s(t) every joint value changes at the
constant rate Δ_i, so

    p' = Σ_rev Δ_i · u_i × (p − o_i) + Σ_pri Δ_j · u_j,   |p'| ≤ W·ρ + S,

since |u_i| = 1 and |p − o_i| ≤ ρ. The same holds for the velocity of every o_i (it is a point
of the chain before joint i): |o_i'| ≤ W·ρ + S. An axis turns only with the revolute joints
before it: |u_i'| ≤ W. Differentiating once more,

    p'' = Σ_rev Δ_i · (u_i' × (p − o_i) + u_i × (p' − o_i')) + Σ_pri Δ_j · u_j'
    |p''| ≤ Σ_rev |Δ_i| · (W·ρ + 2·(W·ρ + S)) + Σ_pri |Δ_j| · W = 3·W²·ρ + 2·W·S + W·S = A.

Let c(t) = (1 − t)·p(0) + t·p(1) be the chord and e = p − c: e(0) = e(1) = 0 and e'' = p''.
For a fixed t and the unit vector n along e(t), f(τ) = n·e(τ) has |f''| ≤ A and vanishes at
both ends, so f(t) ≤ A·t·(1 − t)/2 ≤ A/8: |p(t) − c(t)| ≤ A/8. The distance to a line segment
(a convex set) is convex, so the chord is within max(dist(p(0)), dist(p(1))) of it; the
triangle inequality adds the two. The ends' distances are measured by forward kinematics (the
IK tolerance bounds them), so the bound is computed per pair of samples
(`deviation_bounds`); `tests/geometry/test_cartesian_bound.py` checks it against forward
kinematics at many intermediate points of random motions of the Panda.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trajcache.geometry.model.kinematics import forward_kinematics, prismatic_extent
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import segment_deltas

__all__ = ["ChainWeights", "chain_weights", "deviation_bounds", "distance_to_segment"]


@dataclass(frozen=True)
class ChainWeights:
    """Per state value, how much it turns (rad) or slides (m) the link's chain, and ρ."""

    revolute: FloatArray  # W = Σ revolute[d] · |Δ_d|
    prismatic: FloatArray  # S = Σ prismatic[d] · |Δ_d|
    reach: float  # ρ (m)


def chain_weights(model: RobotModel, link: str) -> ChainWeights:
    """The weights and ρ of the chain from the root to `link` (a planar base's values: 0)."""
    revolute, prismatic = np.zeros(model.dof), np.zeros(model.dof)
    parent_joint = {joint.child: joint for joint in model.joints}
    current, reach, reach_at_first_moving = model.link_names.index(link), 0.0, 0.0
    while current in parent_joint:
        joint = parent_joint[current]
        if joint.index >= model.arm_offset and joint.kind != "fixed":
            weights = prismatic if joint.kind == "prismatic" else revolute
            weights[joint.index] += abs(joint.scale)
            reach_at_first_moving = reach  # the topmost moving joint is met last
        reach += float(np.linalg.norm(joint.origin[:3, 3])) + prismatic_extent(model, joint)
        current = joint.parent
    return ChainWeights(revolute, prismatic, reach_at_first_moving)


def distance_to_segment(points: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Distances of points (n, 3) from the segments a–b (n, 3 each, or one of each)."""
    ab = np.asarray(b, dtype=float) - np.asarray(a, dtype=float)
    ap = np.asarray(points, dtype=float) - a
    length2 = np.sum(ab * ab, axis=-1)
    t = np.where(length2 > 0, np.sum(ap * ab, axis=-1) / np.where(length2 > 0, length2, 1), 0)
    closest = np.clip(t, 0.0, 1.0)[..., None] * ab
    return np.asarray(np.linalg.norm(ap - closest, axis=-1))


def deviation_bounds(
    model: RobotModel,
    link: str,
    states: FloatArray,
    lines: FloatArray,
    line_of: np.ndarray,
) -> FloatArray:
    """For each pair of consecutive states, the bound on the link origin's distance from its
    Cartesian line (module docstring): `lines` (N, 2, 3) are the lines' ends, `line_of[k]` the
    line state k was solved on (the pair k, k + 1 follows the line of k + 1)."""
    array = np.asarray(states, dtype=float)
    if len(array) < 2:
        return np.zeros(0)
    weights = chain_weights(model, link)
    steps = np.abs(segment_deltas(array, base=model.base))
    turn = steps @ weights.revolute
    slide = steps @ weights.prismatic
    bow = (3.0 * turn**2 * weights.reach + 3.0 * turn * slide) / 8.0
    origins = forward_kinematics(model, array)[:, model.link_names.index(link), :3, 3]
    line = np.asarray(line_of)[1:]
    a, b = lines[line, 0], lines[line, 1]
    ends = np.maximum(
        distance_to_segment(origins[:-1], a, b), distance_to_segment(origins[1:], a, b)
    )
    return np.asarray(bow + ends)
