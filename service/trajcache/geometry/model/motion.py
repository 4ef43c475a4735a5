"""How far a point of the robot can move along a straight segment between two states.

Along s(t) = a + t·(b − a), t ∈ [0, 1], the state velocity is constant and a point p of link l
moves with velocity

    v_p = v_base + Σ_d q̇_d · u_d × (p − o_d) + Σ_k q̇_k · u_k

(revolute dofs d with unit axis u_d through o_d, the base heading among them with a vertical axis
through the base origin; prismatic dofs k), so its path is at most

    |Δxy| + Σ_d |Δq_d| · max_t r_d(t) + Σ_k |Δq_k|,    r_d = distance from p to axis d.

`max_t r_d(t)` is bounded from both ends of the segment. The distance from p to axis d does not
change with d itself or with anything upstream of d; only dofs strictly downstream of d move p
relative to that axis, by at most e_d = Σ_{d' after d} |Δq_d'| · c_d'(p) over the segment, where
c_d'(p) is a configuration-independent bound on r_d' (the chain of joint offsets from o_d' to
p's link, plus |p| in its link frame; 1 for a prismatic dof). Hence r_d(t) ≤ r_d(0) + t·e_d and
r_d(t) ≤ r_d(1) + (1 − t)·e_d, and

    max_t r_d(t) ≤ min(c_d(p), (r_d(0) + r_d(1) + e_d) / 2).

Every term of the sum ("lever" of dof d) is returned separately so that pairs of robot links can
drop the dofs that move both links alike: their distance is changed only by the dofs that are an
ancestor of exactly one of them. For a ball of radius ρ around p, each revolute lever grows by at
most ρ·|Δq_d| (its points are within ρ of p).
"""

from __future__ import annotations

import weakref

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.model.kinematics import prismatic_extent
from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

_Axes = tuple[FloatArray, FloatArray]  # origins (..., R, 3) and unit directions (..., R, 3)
_ROUNDING = 1e-7


class MotionBounds:
    """Per-model tables for point motion bounds along straight segments of states."""

    def __init__(self, model: RobotModel) -> None:
        self.model = model
        dof, links = model.dof, len(model.link_names)
        self.planar = model.base is BaseType.PLANAR
        self.rotation = np.zeros(dof, dtype=bool)  # revolute dofs (base heading included)
        axes: dict[int, tuple[int, FloatArray]] = {}  # dof → (link holding it, local axis)
        if self.planar:
            axes[2] = (0, np.array([0.0, 0.0, 1.0]))
        for joint in model.joints:
            if joint.index >= 0 and joint.kind in ("revolute", "continuous"):
                axes[joint.index] = (joint.child, np.asarray(joint.axis, dtype=float))
        self.rotation[list(axes)] = True
        self.rotation_dofs = np.flatnonzero(self.rotation)  # the order of every (…, R) array
        order = [int(d) for d in self.rotation_dofs]
        self.axis_link = np.array([axes[d][0] for d in order], dtype=np.int64)
        self.axis_local = np.array([axes[d][1] for d in order]).reshape(-1, 3)
        # ancestors[l, d]: dof d moves link l; reach[l, d]: bound on |o_l − o_d| (d revolute).
        self.ancestors = np.zeros((links, dof), dtype=bool)
        # drivers[l, d]: an id of the set of joints through which dof d moves link l (one joint,
        # or a leader and the joints that mimic it): two links move alike under d only when
        # they have the same drivers.
        self.drivers = np.zeros((links, dof), dtype=np.int64)
        joint_sets: dict[frozenset[int], int] = {}
        self.reach = np.zeros((links, dof))
        self.after = np.zeros((dof, dof), dtype=bool)  # after[d, d']: d' strictly below d
        parent_joint = {joint.child: joint for joint in model.joints}
        id_of = {joint.name: k for k, joint in enumerate(model.joints)}
        for link in range(links):
            chain: list[int] = []  # dofs from l up to the root
            through: dict[int, set[int]] = {}
            acc = 0.0
            current = link
            while current in parent_joint:
                joint = parent_joint[current]
                if joint.index >= 0:
                    self.ancestors[link, joint.index] = True
                    self.reach[link, joint.index] = acc
                    chain.append(joint.index)
                    through.setdefault(joint.index, set()).add(id_of[joint.name])
                acc += float(np.linalg.norm(joint.origin[:3, 3])) + prismatic_extent(model, joint)
                current = joint.parent
            for d, joints in through.items():
                key = frozenset(joints)
                self.drivers[link, d] = joint_sets.setdefault(key, len(joint_sets) + 1)
            if self.planar:
                self.ancestors[link, :3] = True
                self.drivers[link, :3] = -1  # the base moves every link alike
                self.reach[link, 2] = acc
                chain += [2]
            for lower, d in enumerate(chain):
                self.after[d, chain[:lower]] = True
        self._after_t = self.after.T.astype(float)

    def alike(self, link_a: IntArray, link_b: IntArray) -> BoolArray:
        """(..., D) True where dof d moves links `link_a` and `link_b` as one rigid body: it is
        above both, through the same joints."""
        same = self.drivers[link_a] == self.drivers[link_b]
        return np.asarray(same & self.ancestors[link_a] & self.ancestors[link_b])

    def axes(self, link_tf: FloatArray) -> _Axes:
        """World origins and directions (N, R, 3) of the revolute axes at N poses (N, L, 4, 4)."""
        frames = link_tf[:, self.axis_link]
        axis = self.axis_local
        dirs = (
            frames[..., :3, 0] * axis[:, 0, None]
            + frames[..., :3, 1] * axis[:, 1, None]
            + frames[..., :3, 2] * axis[:, 2, None]
        )
        return frames[..., :3, 3], dirs

    def steps(self, delta: FloatArray) -> FloatArray:
        """|Δ| per dof for state differences (..., D); the base's x column holds |Δxy|."""
        step = np.abs(delta)
        if self.planar:
            step[..., 0] = np.hypot(delta[..., 0], delta[..., 1])
            step[..., 1] = 0.0
        return step

    def coefficients(self, link: IntArray, local_norm: FloatArray) -> FloatArray:
        """c_d(p) (..., D) for points at distance `local_norm` from their link's origin."""
        coef = np.where(self.rotation, self.reach[link] + local_norm[..., None], 1.0)
        return np.where(self.ancestors[link], coef, 0.0)

    def axis_distances(self, points: FloatArray, axes: _Axes) -> FloatArray:
        """r_d (..., R): distance of points (..., 3) from each revolute axis (..., R, 3)."""
        origins, dirs = axes
        dx = points[..., None, 0] - origins[..., 0]
        dy = points[..., None, 1] - origins[..., 1]
        dz = points[..., None, 2] - origins[..., 2]
        along = dx * dirs[..., 0] + dy * dirs[..., 1] + dz * dirs[..., 2]
        square = dx * dx + dy * dy + dz * dz - along * along
        # |p − o|² − ((p − o)·u)² loses up to ~1e-15 m² to rounding: the margin keeps r an
        # upper bound.
        return np.asarray(np.sqrt(np.maximum(square, 0.0)) + _ROUNDING)

    def levers(
        self, r_a: FloatArray, r_b: FloatArray, coef: FloatArray, step: FloatArray
    ) -> FloatArray:
        """Per-dof path bounds (..., D) over a segment of points with axis distances r_a, r_b.

        `coef` from `coefficients` and `step` from `steps`, broadcast against each other and the
        distances from `axis_distances` at both ends; a point's path is at most the sum.
        """
        weighted = step * coef
        spread = weighted @ self._after_t  # e_d
        rot = self.rotation_dofs
        bound = np.minimum(coef[..., rot], (r_a + r_b + spread[..., rot]) / 2.0)
        levers = weighted * np.ones((*bound.shape[:-1], 1))  # a full-shape copy
        levers[..., rot] = step[..., rot] * bound
        return levers

    def turn(self, link: IntArray, step: FloatArray) -> FloatArray:
        """Σ |Δq_d| over the revolute dofs that move each link (..., D) → (..., D) per dof."""
        return np.where(self.rotation & self.ancestors[link], step, 0.0)


_BOUNDS: weakref.WeakKeyDictionary[RobotModel, MotionBounds] = weakref.WeakKeyDictionary()


def motion_bounds(model: RobotModel) -> MotionBounds:
    """The shared MotionBounds of a model (built once)."""
    found = _BOUNDS.get(model)
    if found is None:
        found = MotionBounds(model)
        _BOUNDS[model] = found
    return found
