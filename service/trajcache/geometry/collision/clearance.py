"""Sound lower bounds on the distance of posed robot elements to scene objects and to each other.

Three levels, each tighter and dearer than the one before, and a fourth in `narrow.py`; every one
is a true lower bound (it never exceeds the distance), so any of them may prove clearance:

1. balls: one ball around each element's origin against each object's oriented box (or the other
   element's ball), dense over every state, element and object in one numpy pass;
2. slabs: the support-function bound of `model/support.py` along a few directions (the face normals
   of the object's box and of the element, and the way from the element to its nearest box
   point; for robot pairs the line between the elements, the normal of both their z axes and
   both elements' face normals);
3. sphere covers: every ball of the element's cover against the box (or every ball of the other
   element's cover), plus slabs along the directions those balls suggest;
4. the exact distance, from coal (`narrow.py`): a mesh as its triangles, so a body inside a
   concave mesh's hull but clear of the mesh is settled. FCL's distance value is never used:
   its GJK overestimates some box–cylinder distances by centimetres, which would make a bound
   unsound.

Rows are (state, element, object) for the scene and (state, pair) for the robot itself. Hot
loops avoid numpy reductions over short trailing axes (slow): 3-vectors are summed by component.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.bodies import Posed, RobotGeometry, SceneGeometry
from trajcache.geometry.model.shapes import FloatArray

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
_TINY = 1e-12
_SMALL_BATCH = 8  # states; larger batches cull objects state by state
_FACES = np.vstack([np.eye(3), -np.eye(3)])  # a box's six face normals, in its frame


def norm3(v: FloatArray) -> FloatArray:
    """Euclidean norm over the last axis (length 3)."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.asarray(np.sqrt(x * x + y * y + z * z))


@dataclass
class SceneSpheres:
    """Level 3 for scene rows: every cover ball's bound and its direction to the box."""

    centres: FloatArray  # (K, S, 3)
    lower: FloatArray  # (K, S)
    toward: FloatArray  # (K, S, 3) unit, from the ball's centre to the nearest box point

    def subset(self, keep: BoolArray) -> SceneSpheres:
        """The rows where `keep` is True."""
        return SceneSpheres(self.centres[keep], self.lower[keep], self.toward[keep])


@dataclass
class SelfSpheres:
    """Level 3 for robot pairs: every pair of cover balls."""

    first: FloatArray  # (K, S, 3) centres on the pair's first element
    second: FloatArray  # (K, S', 3)
    lower: FloatArray  # (K, S, S')

    def subset(self, keep: BoolArray) -> SelfSpheres:
        """The rows where `keep` is True."""
        return SelfSpheres(self.first[keep], self.second[keep], self.lower[keep])


class Clearance:
    """Distance bounds (levels 1 to 3) between one robot's
    elements and one scene."""

    def __init__(self, robot: RobotGeometry, scene: SceneGeometry) -> None:
        self.robot = robot
        self.scene = scene
        # (E, M) True where the scene allows the element's link to touch the object: those
        # pairs get no bound (+inf), so no level and no narrow phase ever looks at them.
        self.allowed: BoolArray | None = None
        if scene.scene.allowed and len(scene.ids):
            names = robot.model.link_names
            links = [names[link] for link in robot.element_link]
            self.allowed = np.array(
                [[scene.scene.allows(link, oid) for oid in scene.ids] for link in links],
                dtype=bool,
            ).reshape(len(links), len(scene.ids))
            if not self.allowed.any():
                self.allowed = None

    def near_objects(self, posed: Posed, grow: FloatArray) -> IntArray:
        """Objects whose box meets the box around every element ball grown by `grow` (N, E)."""
        sg = self.scene
        centres = posed.centres
        if len(sg.ids) == 0 or centres.size == 0:
            return np.empty(0, dtype=np.int64)
        reach = self.robot.radius + grow
        lo = np.array([(centres[..., k] - reach).min() for k in range(3)])
        hi = np.array([(centres[..., k] + reach).max() for k in range(3)])
        inside = (sg.aabb_lo <= hi) & (sg.aabb_hi >= lo)
        return np.flatnonzero(inside[:, 0] & inside[:, 1] & inside[:, 2])

    def scene_balls(self, posed: Posed, near: IntArray) -> FloatArray:
        """Level 1: (N, E, len(near)) bounds of element balls against object boxes."""
        sg = self.scene
        centres = posed.centres
        n, e = centres.shape[:2]
        rot = sg.rotation_cat.reshape(3, -1, 3)[:, near].reshape(3, -1)
        local = (centres.reshape(-1, 3) @ rot).reshape(n, e, len(near), 3) - sg.offset[near]
        outside = np.maximum(np.abs(local) - sg.half[near], 0.0)
        bound = norm3(outside) - self.robot.radius[None, :, None]
        if self.allowed is not None:
            bound[:, self.allowed[:, near]] = np.inf
        return bound

    def scene_ball_rows(self, posed: Posed, pad: FloatArray) -> IntArray:
        """Level 1 as rows (K, 3): (state, element, object) whose ball bound is within `pad`
        (N, E). Objects are culled per state, which pays off for batches spread over a scene."""
        sg = self.scene
        centres = posed.centres
        if len(sg.ids) == 0 or centres.size == 0:
            return np.empty((0, 3), dtype=np.int64)
        if len(centres) <= _SMALL_BATCH:  # one cull for the whole batch is cheaper
            near = self.near_objects(posed, pad)
            state, element, obj = np.nonzero(self.scene_balls(posed, near) <= pad[:, :, None])
            return np.column_stack([state, element, near[obj]])
        reach = (self.robot.radius + pad)[..., None]
        lo, hi = (centres - reach).min(axis=1), (centres + reach).max(axis=1)  # (N, 3)
        meets = np.ones((len(centres), len(sg.ids)), dtype=bool)
        for axis in range(3):
            meets &= (sg.aabb_lo[:, axis] <= hi[:, axis, None]) & (
                sg.aabb_hi[:, axis] >= lo[:, axis, None]
            )
        state, obj = np.nonzero(meets)
        local = (centres[state] - sg.position[obj][:, None]) @ sg.rotation[obj]  # (K, E, 3)
        outside = np.maximum(np.abs(local) - sg.half[obj][:, None], 0.0)
        bound = norm3(outside) - self.robot.radius
        if self.allowed is not None:
            bound[self.allowed[:, obj].T] = np.inf
        pick, element = np.nonzero(bound <= pad[state])
        return np.column_stack([state[pick], element, obj[pick]])

    def self_balls(self, posed: Posed) -> FloatArray:
        """Level 1: (N, P) bounds between the element balls of every robot pair."""
        rg = self.robot
        gap = posed.centres[:, rg.pair_i] - posed.centres[:, rg.pair_j]
        return norm3(gap) - rg.radius[rg.pair_i] - rg.radius[rg.pair_j]

    def scene_slabs(self, posed: Posed, rows: IntArray, *, exact: bool = True) -> FloatArray:
        """Level 2 for scene rows: slabs along the box's and the element's face normals and
        from the element towards the box's nearest point (meshes as their boxes unless
        `exact`)."""
        if len(rows) == 0:
            return np.zeros(0)
        sample, element, obj = rows.T
        sg = self.scene
        rot, pos = sg.rotation[obj], sg.position[obj]
        pose = posed.pose(sample, element)
        local = ((pose[:, :3, 3] - pos)[:, None, :] @ rot)[:, 0]
        half = sg.half[obj]
        nearest = np.clip(local, -half, half) - local
        toward = (nearest[:, None, :] @ rot.transpose(0, 2, 1))[:, 0]
        faces = _FACES @ rot.transpose(0, 2, 1)  # (K, 6, 3)
        own = _FACES @ pose[:, :3, :3].transpose(0, 2, 1)
        dirs = np.concatenate([faces, own, toward[:, None]], axis=1)
        return self.scene_slab(posed, rows, dirs, pose, exact=exact)

    def self_slabs(self, posed: Posed, rows: IntArray, *, exact: bool = True) -> FloatArray:
        """Level 2 for robot pairs: slabs along the line between the elements, across both
        their axes and along each element's face normals (meshes as their boxes unless
        `exact`)."""
        if len(rows) == 0:
            return np.zeros(0)
        sample, pair = rows.T
        ei, ej = self.robot.pair_i[pair], self.robot.pair_j[pair]
        poses = (posed.pose(sample, ei), posed.pose(sample, ej))
        between = poses[1][:, :3, 3] - poses[0][:, :3, 3]
        across = _cross(poses[0][:, :3, 2], poses[1][:, :3, 2])
        dirs = np.concatenate(
            [
                np.stack([between, across, -across], axis=1),
                _FACES @ poses[0][:, :3, :3].transpose(0, 2, 1),
                _FACES @ poses[1][:, :3, :3].transpose(0, 2, 1),
            ],
            axis=1,
        )
        return self.self_slab(posed, rows, dirs, poses, exact=exact)

    def scene_spheres(self, posed: Posed, rows: IntArray) -> SceneSpheres:
        """Level 3 for scene rows (K, 3): the element's cover balls against the object's box."""
        sample, element, obj = rows.T
        sg = self.scene
        centres = posed.spheres(sample, element, self.robot)
        rot, pos = sg.rotation[obj], sg.position[obj]
        local = (centres - pos[:, None]) @ rot  # Rᵀ(c − t) row by row
        half = sg.half[obj][:, None]
        gap = np.clip(local, -half, half) - local
        dist = norm3(gap)
        toward = (gap / np.maximum(dist, _TINY)[..., None]) @ rot.transpose(0, 2, 1)
        lower = dist - self.robot.sphere_radius[element, : centres.shape[1]]
        return SceneSpheres(centres, lower, toward)

    def self_spheres(self, posed: Posed, rows: IntArray) -> SelfSpheres:
        """Level 3 for robot-pair rows (K, 2): every ball of one cover against the other's."""
        rg = self.robot
        sample, pair = rows.T
        ei, ej = rg.pair_i[pair], rg.pair_j[pair]
        first, second = posed.spheres(sample, ei, rg), posed.spheres(sample, ej, rg)
        dist = norm3(second[:, None, :, :] - first[:, :, None, :])
        ri = rg.sphere_radius[ei, : first.shape[1], None]
        rj = rg.sphere_radius[ej, None, : second.shape[1]]
        return SelfSpheres(first, second, dist - ri - rj)

    def scene_cover_slabs(self, posed: Posed, rows: IntArray, spheres: SceneSpheres) -> FloatArray:
        """Level 3 slabs for scene rows: along each cover ball's way to the box."""
        if len(rows) == 0:
            return np.zeros(0)
        return self.scene_slab(posed, rows, spheres.toward)

    def self_cover_slabs(self, posed: Posed, rows: IntArray, spheres: SelfSpheres) -> FloatArray:
        """Level 3 slabs for robot pairs: between the four closest pairs of cover balls."""
        if len(rows) == 0:
            return np.zeros(0)
        k, sa, sb = spheres.lower.shape
        best = np.argsort(spheres.lower.reshape(k, -1), axis=1)[:, : min(4, sa * sb)]
        a, b = np.divmod(best, sb)
        rk = np.arange(k)[:, None]
        return self.self_slab(posed, rows, spheres.second[rk, b] - spheres.first[rk, a])

    def scene_slab(
        self,
        posed: Posed,
        rows: IntArray,
        dirs: FloatArray,
        pose: FloatArray | None = None,
        *,
        exact: bool = True,
    ) -> FloatArray:
        """max over directions (K, Q, 3) of the slab bound between element and object."""
        sample, element, obj = rows.T
        pose = posed.pose(sample, element) if pose is None else pose
        sg = self.scene
        robot = self.robot.support.support if exact else self.robot.support.coarse
        scene = sg.support.support if exact else sg.support.coarse
        return _slab(
            _unit(dirs),
            (pose[:, :3, :3], pose[:, :3, 3], robot, element),
            (sg.rotation[obj], sg.position[obj], scene, obj),
        )

    def self_slab(
        self,
        posed: Posed,
        rows: IntArray,
        dirs: FloatArray,
        poses: tuple[FloatArray, FloatArray] | None = None,
        *,
        exact: bool = True,
    ) -> FloatArray:
        """max over directions (K, Q, 3) of the slab bound between the elements of a pair."""
        sample, pair = rows.T
        ei, ej = self.robot.pair_i[pair], self.robot.pair_j[pair]
        pi, pj = poses if poses is not None else (posed.pose(sample, ei), posed.pose(sample, ej))
        table = self.robot.support
        support = table.support if exact else table.coarse
        return _slab(
            _unit(dirs),
            (pi[:, :3, :3], pi[:, :3, 3], support, ei),
            (pj[:, :3, :3], pj[:, :3, 3], support, ej),
        )


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross products of (K, 3) rows (np.cross is slow on small arrays)."""
    return np.column_stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ]
    )


def _unit(dirs: FloatArray) -> FloatArray:
    """Unit directions; a zero vector becomes +z (any unit direction gives a valid bound)."""
    norm = norm3(dirs)[..., None]
    return np.where(norm > _TINY, dirs / np.maximum(norm, _TINY), np.array([0.0, 0.0, 1.0]))


_Support = Callable[[IntArray, FloatArray], FloatArray]
_Body = tuple[FloatArray, FloatArray, _Support, IntArray]  # rotation, position, support, index


def _slab(dirs: FloatArray, a: _Body, b: _Body) -> FloatArray:
    """max over unit world directions n (K, Q, 3) of n·t_B − h_B(−R_Bᵀn) − n·t_A − h_A(R_Aᵀn)."""
    rot_a, pos_a, support_a, index_a = a
    rot_b, pos_b, support_b, index_b = b
    h_a = support_a(index_a[:, None], dirs @ rot_a)  # row q of n @ R is R_Aᵀ n_q
    h_b = support_b(index_b[:, None], -dirs @ rot_b)
    gap = (dirs @ (pos_b - pos_a)[:, :, None])[..., 0]
    return np.asarray(np.maximum((gap - h_a - h_b).max(axis=1, initial=-np.inf), 0.0))
