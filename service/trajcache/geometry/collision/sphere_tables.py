"""The arrays `compiled/spheres.sphere_state` takes: a model's sphere covers, a scene's objects.

Built from a `CollisionChecker`, so the elements (attached objects included, in a scene's model
variant), the self-collision pairs still checked and the pairs the scene allows are exactly the
ones the exact check uses.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
import trimesh

from trajcache.geometry.collision.bodies import RobotGeometry
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.collision.compiled.spheres import BOX, CAPSULE, CYLINDER, MESH, SPHERE
from trajcache.geometry.model.kinematics import fk_tables
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.support import sphere_cover

_KINDS = {
    ShapeKind.BOX: BOX,
    ShapeKind.SPHERE: SPHERE,
    ShapeKind.CYLINDER: CYLINDER,
    ShapeKind.CAPSULE: CAPSULE,
    ShapeKind.MESH: MESH,
}
PLANNER_CELLS = 8  # cells along a box's or mesh's longest side in the planner's covers
_COVERS: weakref.WeakKeyDictionary[RobotGeometry, tuple[np.ndarray, ...]] = (
    weakref.WeakKeyDictionary()
)


def surface_reach(shape: Shape, centres: FloatArray) -> FloatArray:
    """Per cover ball centre of `shape` (local frame): how far it may be from a point of the
    shape that FCL tests, so that the centre lying deeper than that inside an object proves
    contact. A primitive is a solid and holds its cover's centres: 0. A mesh is its triangles:
    the exact distance to the nearest one (trimesh), grown by a micrometre for round-off."""
    if shape.kind is not ShapeKind.MESH:
        return np.zeros(len(centres))
    assert shape.vertices is not None and shape.faces is not None
    mesh = trimesh.Trimesh(shape.vertices, shape.faces, process=False)
    _, distance, _ = trimesh.proximity.closest_point(mesh, centres)
    return np.asarray(distance, dtype=float) + 1e-6


def planner_covers(robot: RobotGeometry) -> tuple[np.ndarray, ...]:
    """Every element's finer sphere cover (`PLANNER_CELLS`) in its link's frame: counts (E,),
    centres (E, W, 3), radii (E, W) and surface reach (E, W), padded by repeating ball 0."""
    covers = _COVERS.get(robot)
    if covers is None:
        elements = robot.model.elements
        raw = [sphere_cover(e.shape, PLANNER_CELLS) for e in elements]
        width = max((len(r) for _, r in raw), default=1)
        count = np.array([len(r) for _, r in raw], dtype=np.int64)
        local, radius, reach = (
            np.zeros((len(raw), width, 3)),
            np.zeros((len(raw), width)),
            np.zeros((len(raw), width)),
        )
        for k, ((centres, radii), element) in enumerate(zip(raw, elements, strict=True)):
            fill = np.r_[np.arange(len(radii)), np.zeros(width - len(radii), dtype=np.int64)]
            placed = centres @ element.origin[:3, :3].T + element.origin[:3, 3]
            local[k], radius[k] = placed[fill], radii[fill]
            reach[k] = surface_reach(element.shape, centres)[fill]
        covers = (count, local, radius, reach)
        _COVERS[robot] = covers
    return covers


@dataclass(frozen=True)
class SphereTables:
    """Forward kinematics, robot, scene and pair arrays, and a work buffer."""

    fk: tuple[object, ...]
    links: int
    robot: tuple[np.ndarray, ...]
    scene: tuple[np.ndarray, ...]
    pairs: tuple[np.ndarray, ...]

    def work(self) -> tuple[np.ndarray, ...]:
        """A fresh work buffer (one per thread)."""
        links = self.links
        elements, width = self.robot[4].shape[:2]
        return (
            np.zeros((1, links, 4, 4)),
            np.zeros((elements, 3)),
            np.zeros((elements, width, 3)),
            np.zeros(elements, dtype=np.bool_),
        )


def _object_size(shape: Shape) -> list[float]:
    if shape.kind is ShapeKind.BOX:
        return [float(v) / 2.0 for v in shape.size]
    if shape.kind is ShapeKind.SPHERE:
        return [float(shape.size[0]), 0.0, 0.0]
    if shape.kind in (ShapeKind.CYLINDER, ShapeKind.CAPSULE):
        radius, length = shape.size
        return [float(radius), float(length) / 2.0, 0.0]
    return [float(v) for v in shape.half_extents()]


def sphere_tables(checker: CollisionChecker) -> SphereTables:
    """The arrays of one model (variant) in one scene."""
    robot, scene = checker.robot, checker.scene
    elements = len(robot.model.elements)
    objects = scene.scene.objects
    kinds = np.array([_KINDS[o.shape.kind] for o in objects], dtype=np.int64)
    position = np.array([o.pose[:3, 3] for o in objects], dtype=float).reshape(-1, 3)
    allowed = checker.clearance.allowed
    if allowed is None:
        allowed = np.zeros((elements, len(objects)), dtype=np.bool_)
    return SphereTables(
        fk=fk_tables(robot.model),
        links=len(robot.model.link_names),
        robot=(
            np.ascontiguousarray(robot.element_link),
            np.ascontiguousarray(robot.element_origin[:, :3, 3]),
            np.ascontiguousarray(robot.radius, dtype=float),
            *(np.ascontiguousarray(a) for a in planner_covers(robot)),
        ),
        scene=(
            kinds,
            np.ascontiguousarray(np.array([o.pose[:3, :3] for o in objects]).reshape(-1, 3, 3)),
            np.ascontiguousarray(position),
            np.ascontiguousarray(np.array([_object_size(o.shape) for o in objects]).reshape(-1, 3)),
            np.ascontiguousarray(allowed, dtype=np.bool_),
        ),
        pairs=(np.ascontiguousarray(robot.pair_i), np.ascontiguousarray(robot.pair_j)),
    )
