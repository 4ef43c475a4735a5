"""Collision bodies: a model's elements and a scene's objects as FCL objects and bound tables.

Both are built once (per model, per scene version: `shared.py`) and shared read-only between
threads; only the robot's FCL objects, whose transforms a check mutates, are per thread. `Posed`
holds a batch of states posed by forward kinematics, everything the distance bounds need.
"""

from __future__ import annotations

import functools
import threading
from dataclasses import dataclass

import coal
import fcl
import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.model.kinematics import forward_kinematics
from trajcache.geometry.model.motion import MotionBounds, motion_bounds
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape
from trajcache.geometry.model.support import SupportTable, sphere_cover
from trajcache.geometry.scene.scene import Scene

IntArray = NDArray[np.int64]


class RobotGeometry:
    """FCL geometry, bounding balls, sphere covers and self-collision pairs of a model."""

    def __init__(self, model: RobotModel) -> None:
        self.model = model
        self.motion: MotionBounds = motion_bounds(model)
        elements = model.elements
        self.geometries = [e.shape.to_fcl() for e in elements]
        self.exact = ExactBodies.of([e.shape for e in elements])
        self.gaps = self.exact.gaps
        self.element_link = np.array([e.link for e in elements], dtype=np.int64)
        self.element_origin = np.array([e.origin for e in elements], dtype=float).reshape(-1, 4, 4)
        self.support = SupportTable.build([e.shape for e in elements])
        # Level 1: a ball around each element's origin, and its box's half extents.
        self.radius = np.array([e.shape.bounding_radius() for e in elements], dtype=float)
        self.element_half = np.array(
            [e.shape.half_extents() for e in elements], dtype=float
        ).reshape(-1, 3)
        local_origin = self.element_origin[:, :3, 3]
        self.centre_coef = self.motion.coefficients(
            self.element_link, np.linalg.norm(local_origin, axis=1)
        )
        # Level 2: sphere covers, in link frames, padded to a common count by repeating a ball.
        covers = [sphere_cover(e.shape) for e in elements]
        width = max((len(c[1]) for c in covers), default=1)
        self.sphere_count = np.array([len(c[1]) for c in covers], dtype=np.int64)
        self.sphere_local = np.zeros((len(elements), width, 3))
        self.sphere_radius = np.zeros((len(elements), width))
        for k, (centres, radii) in enumerate(covers):
            fill = np.r_[np.arange(len(radii)), np.zeros(width - len(radii), dtype=np.int64)]
            placed = centres @ self.element_origin[k, :3, :3].T + local_origin[k]
            self.sphere_local[k], self.sphere_radius[k] = placed[fill], radii[fill]
        self.sphere_coef = self.motion.coefficients(
            self.element_link[:, None], np.linalg.norm(self.sphere_local, axis=-1)
        )
        allowed = model.allowed_pairs
        pairs = [
            (i, j)
            for i in range(len(elements))
            for j in range(i + 1, len(elements))
            if elements[i].link != elements[j].link
            and (min(elements[i].link, elements[j].link), max(elements[i].link, elements[j].link))
            not in allowed
        ]
        self.pair_i = np.array([p[0] for p in pairs], dtype=np.int64)
        self.pair_j = np.array([p[1] for p in pairs], dtype=np.int64)
        # The dofs that change a pair's distance: those that move one of its elements, and not
        # both alike (as `free_pairs`); a dof that moves neither changes nothing either.
        li, lj = self.element_link[self.pair_i], self.element_link[self.pair_j]
        above = self.motion.ancestors[li] | self.motion.ancestors[lj]
        self.pair_mask = above & ~self.motion.alike(li, lj)  # (P, D)
        self.proven_free: list[tuple[int, int]] = []  # element pairs dropped by `drop_pairs`
        self._local = threading.local()

    def pair_motion(self) -> tuple[FloatArray, FloatArray]:
        """Configuration-independent relative motion per unit step of each dof, (D, P): of the
        pairs' element centres, and of any point of the whole elements."""
        turning = self.motion.rotation & self.motion.ancestors
        i, j, mask = self.pair_i, self.pair_j, self.pair_mask
        centre = ((self.centre_coef[i] + self.centre_coef[j]) * mask).T
        turn_i = (turning[self.element_link[i]] & mask) * self.radius[i, None]
        turn_j = (turning[self.element_link[j]] & mask) * self.radius[j, None]
        return centre, centre + (turn_i + turn_j).T

    @functools.cached_property
    def kernel_robot(self) -> tuple[np.ndarray, ...]:
        """Elements, balls, sphere covers and motion coefficients as the compiled levels take
        them (`compiled.scene_open_kernel`)."""
        turning = self.motion.rotation & self.motion.ancestors
        return (
            self.element_link,
            np.ascontiguousarray(self.element_origin),
            np.ascontiguousarray(self.radius, dtype=float),
            np.ascontiguousarray(self.centre_coef, dtype=float),
            np.ascontiguousarray(turning),
            self.sphere_count,
            np.ascontiguousarray(self.sphere_local),
            np.ascontiguousarray(self.sphere_radius),
            np.ascontiguousarray(self.sphere_coef, dtype=float),
        )

    @functools.cached_property
    def kernel_motion(self) -> tuple[np.ndarray, ...]:
        """The revolute dofs and their axes as the compiled levels take them."""
        mb = self.motion
        index = np.full(len(mb.rotation), -1, dtype=np.int64)
        index[mb.rotation_dofs] = np.arange(len(mb.rotation_dofs))
        return (
            np.ascontiguousarray(mb.rotation),
            index,
            np.ascontiguousarray(mb.after),
            np.ascontiguousarray(mb.axis_link, dtype=np.int64),
            np.ascontiguousarray(mb.axis_local, dtype=float),
        )

    @functools.cached_property
    def kernel_pairs(self) -> tuple[np.ndarray, ...]:
        """The self-collision pairs as the compiled levels take them (after `drop_pairs`)."""
        centre, whole = self.pair_motion()
        return (
            np.ascontiguousarray(self.pair_i),
            np.ascontiguousarray(self.pair_j),
            np.ascontiguousarray(self.pair_mask, dtype=float),
            np.ascontiguousarray(centre, dtype=float),
            np.ascontiguousarray(whole, dtype=float),
        )

    def drop_pairs(self, drop: NDArray[np.bool_]) -> None:
        """Stop checking the self-collision pairs where `drop` (P,) is True.

        Only for pairs proven never to collide within the joint limits (`free_pairs`), and
        only before the geometry is shared.
        """
        self.proven_free += [
            (int(i), int(j)) for i, j in zip(self.pair_i[drop], self.pair_j[drop], strict=True)
        ]
        keep = ~np.asarray(drop, dtype=bool)
        self.pair_i, self.pair_j = self.pair_i[keep], self.pair_j[keep]
        self.pair_mask = self.pair_mask[keep]
        self.__dict__.pop("kernel_pairs", None)

    def skipped_link_pairs(self) -> list[tuple[str, str, str]]:
        """Every link pair whose self-collisions are not checked, with the reason: the model's
        (`adjacent`, `rigid`, `srdf`), or `proven` when every element pair of the two links was
        proven free (`drop_pairs`)."""
        names = self.model.link_names
        out = [(names[a], names[b], why) for (a, b), why in sorted(self.model.pair_reasons.items())]
        link = self.element_link

        def links(i: int, j: int) -> tuple[int, int]:
            a, b = int(link[i]), int(link[j])
            return min(a, b), max(a, b)

        checked = {links(i, j) for i, j in zip(self.pair_i, self.pair_j, strict=True)}
        proven = {links(i, j) for i, j in self.proven_free} - checked
        return out + [(names[a], names[b], "proven") for a, b in sorted(proven)]

    def objects(self) -> list[fcl.CollisionObject]:
        """This thread's FCL objects (transforms are mutated during a check)."""
        objs: list[fcl.CollisionObject] | None = getattr(self._local, "objects", None)
        if objs is None:
            objs = [fcl.CollisionObject(g, fcl.Transform()) for g in self.geometries]
            self._local.objects = objs
        return objs


@dataclass(frozen=True)
class ExactBodies:
    """coal's geometries of some shapes (`narrow.py`, `pair_tables.py`; FCL's distances can be
    too large): each shape's own (a mesh as its triangles), its convex hull (the shape itself
    for a primitive), and how far the hull strays from the shape (`Shape.hull_gap`)."""

    exact: list[coal.CollisionGeometry]
    hull: list[coal.CollisionGeometry]
    gaps: FloatArray

    @classmethod
    def of(cls, shapes: list[Shape], gaps: FloatArray | None = None) -> ExactBodies:
        """The coal geometries of `shapes` (`gaps`: their `hull_gaps`, if known)."""
        exact = [s.to_coal() for s in shapes]
        hull = [s.to_coal_hull(g) for s, g in zip(shapes, exact, strict=True)]
        return cls(exact, hull, hull_gaps(shapes) if gaps is None else gaps)


def hull_gaps(shapes: list[Shape]) -> FloatArray:
    """Per shape, how far its convex hull strays from it (`Shape.hull_gap`; 0 for a primitive)."""
    return np.array([s.hull_gap() for s in shapes], dtype=float)


class SceneGeometry:
    """FCL and coal objects, oriented bounding boxes and support tables of one scene version."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.ids = [o.id for o in scene.objects]
        self.objects = [
            fcl.CollisionObject(o.shape.to_fcl(), fcl.Transform(o.pose[:3, :3], o.pose[:3, 3]))
            for o in scene.objects
        ]
        count = len(scene.objects)
        self.rotation = np.array([o.pose[:3, :3] for o in scene.objects]).reshape(count, 3, 3)
        self.position = np.array([o.pose[:3, 3] for o in scene.objects]).reshape(count, 3)
        self.half = np.array([o.shape.half_extents() for o in scene.objects]).reshape(count, 3)
        self.support = SupportTable.build([o.shape for o in scene.objects])
        # local = Rᵀ(c − t) for every object in one matmul: c @ [R_0 | R_1 | …] − tᵀR.
        self.rotation_cat = np.ascontiguousarray(self.rotation.transpose(1, 0, 2).reshape(3, -1))
        self.offset = np.einsum("mj,mji->mi", self.position, self.rotation)
        reach = np.einsum("mij,mj->mi", np.abs(self.rotation), self.half)
        self.aabb_lo, self.aabb_hi = self.position - reach, self.position + reach
        self.kernel_scene = tuple(
            np.ascontiguousarray(a, dtype=float)
            for a in (self.rotation, self.position, self.half, self.aabb_lo, self.aabb_hi)
        )

    @functools.cached_property
    def exact(self) -> ExactBodies:
        """coal's geometries of the objects, built on first use: only concave meshes near the
        robot need them."""
        return ExactBodies.of([o.shape for o in self.scene.objects], self.gaps)

    @functools.cached_property
    def gaps(self) -> FloatArray:
        """Per object, how far its convex hull strays from it (`Shape.hull_gap`)."""
        return hull_gaps([o.shape for o in self.scene.objects])

    @functools.cached_property
    def poses(self) -> FloatArray:
        """(M, 4, 4) the objects' poses, as the compiled exact level takes them."""
        return np.ascontiguousarray(
            np.array([o.pose for o in self.scene.objects], dtype=float).reshape(-1, 4, 4)
        )


@dataclass
class Posed:
    """A batch of states posed by forward kinematics, with what every bound level needs."""

    robot: RobotGeometry
    states: FloatArray  # (N, D)
    links: FloatArray  # (N, L, 4, 4)

    @classmethod
    def build(cls, robot: RobotGeometry, states: FloatArray) -> Posed:
        """Forward kinematics of checked `states` (N, D), once for every use."""
        return cls(robot, states, forward_kinematics(robot.model, states))

    @functools.cached_property
    def centres(self) -> FloatArray:
        """(N, E, 3) element origins: the centres of the level-1 balls."""
        robot = self.robot
        frames = self.links[:, robot.element_link]  # (N, E, 4, 4)
        local = robot.element_origin[:, :3, 3]
        return np.asarray(
            frames[..., :3, 0] * local[:, 0, None]
            + frames[..., :3, 1] * local[:, 1, None]
            + frames[..., :3, 2] * local[:, 2, None]
            + frames[..., :3, 3]
        )

    @functools.cached_property
    def axes(self) -> tuple[FloatArray, FloatArray]:
        """World origins and directions (N, R, 3) of the revolute axes (for motion bounds)."""
        return self.robot.motion.axes(self.links)

    @property
    def axis_origins(self) -> FloatArray:
        """(N, R, 3) points on the revolute axes."""
        return self.axes[0]

    @property
    def axis_dirs(self) -> FloatArray:
        """(N, R, 3) unit directions of the revolute axes."""
        return self.axes[1]

    def pose(self, sample: IntArray, element: IntArray) -> FloatArray:
        """World poses (K, 4, 4) of `element` at `sample` (both (K,))."""
        rg = self.robot
        return np.asarray(self.links[sample, rg.element_link[element]] @ rg.element_origin[element])

    @functools.cached_property
    def elements(self) -> FloatArray:
        """World poses (N, E, 4, 4) of every element at every state."""
        rg = self.robot
        return np.asarray(self.links[:, rg.element_link] @ rg.element_origin[None])

    def spheres(self, sample: IntArray, element: IntArray, robot: RobotGeometry) -> FloatArray:
        """World centres (K, S, 3) of the sphere covers of `element` at `sample` (both (K,)).

        S is the largest cover among these elements; smaller covers repeat their first ball.
        """
        width = int(robot.sphere_count[element].max(initial=1))
        frame = self.links[sample, robot.element_link[element]]  # (K, 4, 4)
        local = robot.sphere_local[element, :width]  # (K, S, 3)
        return np.asarray(local @ frame[:, :3, :3].transpose(0, 2, 1) + frame[:, None, :3, 3])
