"""The arrays `compiled/spheres.sphere_state` takes: a model's sphere trees, a scene's objects.

Built from a `CollisionChecker`, so the elements (attached objects included, in a scene's model
variant), the self-collision pairs still checked and the pairs the scene allows are exactly the
ones the exact check uses.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from trajcache.geometry.collision.bodies import RobotGeometry
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.collision.compiled.spheres import BOX, CAPSULE, CYLINDER, MESH, SPHERE
from trajcache.geometry.collision.pair_tables import pair_tables
from trajcache.geometry.model.kinematics import fk_tables
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.sphere_tree import sphere_tree

_KINDS = {
    ShapeKind.BOX: BOX,
    ShapeKind.SPHERE: SPHERE,
    ShapeKind.CYLINDER: CYLINDER,
    ShapeKind.CAPSULE: CAPSULE,
    ShapeKind.MESH: MESH,
}
_TREES: weakref.WeakKeyDictionary[RobotGeometry, tuple[np.ndarray, ...]] = (
    weakref.WeakKeyDictionary()
)
STACK = 4096  # nodes (and node pairs) a descent may hold at once


def planner_trees(robot: RobotGeometry) -> tuple[np.ndarray, ...]:
    """Every element's sphere tree (`model/sphere_tree.py`) packed, centres in the frame of the
    element's link: element link (E,), root (E,), centres (N, 3), radii (N,), first child (N,),
    child count (N,), reach (N,). Built once per model (variant)."""
    packed = _TREES.get(robot)
    if packed is None:
        roots, parts, offset = [], [], 0
        for element in robot.model.elements:
            tree = sphere_tree(element.shape)
            roots.append(offset)
            centre = tree.centre @ element.origin[:3, :3].T + element.origin[:3, 3]
            first = np.where(tree.first_child >= 0, tree.first_child + offset, -1)
            parts.append((centre, tree.radius, first, tree.children, tree.reach))
            offset += len(tree.radius)
        packed = (
            np.ascontiguousarray(robot.element_link),
            np.array(roots, dtype=np.int64),
            *(np.ascontiguousarray(np.concatenate([p[k] for p in parts])) for k in range(5)),
        )
        _TREES[robot] = packed
    return packed


@dataclass(frozen=True)
class SphereTables:
    """Forward kinematics, robot, scene and pair arrays, and a work buffer."""

    fk: tuple[object, ...]
    links: int
    robot: tuple[object, ...]
    scene: tuple[object, ...]
    pairs: tuple[np.ndarray, ...]

    def work(self) -> tuple[np.ndarray, ...]:
        """A fresh work buffer (one per thread)."""
        nodes = len(self.robot[3])  # type: ignore[arg-type]
        return (
            np.zeros((1, self.links, 4, 4)),
            np.zeros((nodes, 3)),
            np.full(nodes, -1, dtype=np.int64),
            np.zeros(1, dtype=np.int64),
            np.zeros(STACK, dtype=np.int64),
            np.zeros((STACK, 2), dtype=np.int64),
            np.zeros((len(self.robot[1]), 3, 4)),  # type: ignore[arg-type]
            np.zeros(2, dtype=np.int64),
            np.zeros((len(self.robot[1]), 3)),  # type: ignore[arg-type]
            np.full(len(self.robot[1]), -1, dtype=np.int64),  # type: ignore[arg-type]
            np.zeros((len(self.robot[1]), 4)),  # type: ignore[arg-type]
            np.zeros((4, 3)),  # GJK's simplex
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


_BOXES: weakref.WeakKeyDictionary[RobotGeometry, tuple[np.ndarray, np.ndarray]] = (
    weakref.WeakKeyDictionary()
)


def _element_boxes(robot: RobotGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Each element's box in its own frame (centre, half extents): a mesh's vertices' box, a
    primitive's own (about its origin). Built once per model (variant)."""
    boxes = _BOXES.get(robot)
    if boxes is None:
        boxes = _BOXES[robot] = _boxes(robot)
    return boxes


def _boxes(robot: RobotGeometry) -> tuple[np.ndarray, np.ndarray]:
    centres, halves = [], []
    for element in robot.model.elements:
        shape = element.shape
        if shape.kind is ShapeKind.MESH and shape.vertices is not None:
            lo, hi = shape.vertices.min(axis=0), shape.vertices.max(axis=0)
            centres.append((lo + hi) / 2.0)
            halves.append((hi - lo) / 2.0 + 1e-9)
        else:
            centres.append(np.zeros(3))
            halves.append(np.asarray(shape.half_extents(), dtype=float) + 1e-9)
    return (
        np.ascontiguousarray(np.array(centres, dtype=float).reshape(-1, 3)),
        np.ascontiguousarray(np.array(halves, dtype=float).reshape(-1, 3)),
    )


def sphere_tables(checker: CollisionChecker, table_budget_s: float = math.inf) -> SphereTables:
    """The arrays of one model (variant) in one scene."""
    robot, scene = checker.robot, checker.scene
    elements = len(robot.model.elements)
    objects = scene.scene.objects
    kinds = np.array([_KINDS[o.shape.kind] for o in objects], dtype=np.int64)
    position = np.array([o.pose[:3, 3] for o in objects], dtype=float).reshape(-1, 3)
    half = np.ascontiguousarray(scene.half, dtype=float).reshape(-1, 3)
    allowed = checker.clearance.allowed
    if allowed is None:
        allowed = np.zeros((elements, len(objects)), dtype=np.bool_)
    return SphereTables(
        fk=fk_tables(robot.model),
        links=len(robot.model.link_names),
        robot=(
            *planner_trees(robot),
            np.ascontiguousarray(robot.element_origin),
            robot.support.kernel_args,
            *_element_boxes(robot),
        ),
        scene=(
            kinds,
            np.ascontiguousarray(np.array([o.pose[:3, :3] for o in objects]).reshape(-1, 3, 3)),
            np.ascontiguousarray(position),
            np.ascontiguousarray(np.array([_object_size(o.shape) for o in objects]).reshape(-1, 3)),
            np.ascontiguousarray(allowed, dtype=np.bool_),
            np.ascontiguousarray(np.array([o.pose[:3, :] for o in objects]).reshape(-1, 3, 4)),
            scene.support.kernel_args,
            half,
            np.sqrt((half**2).sum(axis=1)) + 1e-9,  # the boxes' bounding balls (round-off: grown)
        ),
        pairs=(
            np.ascontiguousarray(robot.pair_i),
            np.ascontiguousarray(robot.pair_j),
            *pair_tables(robot, table_budget_s),
        ),
    )
