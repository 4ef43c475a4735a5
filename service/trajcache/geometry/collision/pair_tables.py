"""Distance tables of the self-collision pairs that only one or two joints move relative to each
other (a wrist's links against the forearm), for the compiled planner's state check.

Such a pair's distance d(q) depends on those joints' values only: every other joint moves both
elements alike (`RobotGeometry.pair_mask`). It is bounded from below at the nodes g of a grid
over their limits by coal's distance between the elements' convex hulls, which hold them, or
where that is under `HULL_ENOUGH_M`, measured exactly (coal on the triangles); both less the
narrow phase's `EXACT_MARGIN`. For any state q and the
nearest node g, moving from g to q along a straight line in those values moves any point of one
element relative to the other by at most Σ_d M_d |q_d − g_d|, with M_d the pair's
configuration-independent motion bound per unit of joint d (`RobotGeometry.pair_motion`, the
certification's). Distance is 1-Lipschitz in that motion, so

    d(q) ≥ d(g) − Σ_d M_d |q_d − g_d|,

and a positive right side proves the pair apart at q. A table is built once per model (variant)
and process, when a plan first needs it.
"""

from __future__ import annotations

import math
import time
import weakref

import coal
import numpy as np

from trajcache.core.lru import LRU
from trajcache.geometry.collision.bodies import RobotGeometry
from trajcache.geometry.collision.narrow import EXACT_MARGIN
from trajcache.geometry.disk_cache import cached_arrays, digest
from trajcache.geometry.model.kinematics import element_transforms, fk_tables, forward_kinematics

STEP_RAD = 0.06  # grid step of a joint's values (metres for a prismatic joint)
MAX_NODES = 30_000  # a pair whose grid would be larger gets no table
HULL_ENOUGH_M = 0.05  # a hull distance at least this large is stored as the node's bound
_TABLES: weakref.WeakKeyDictionary[RobotGeometry, tuple[np.ndarray, ...]] = (
    weakref.WeakKeyDictionary()
)
# One pair's distances by what they depend on (model variants of one robot share them): the
# kinematic tables, the two elements' shapes and origins, and the grid.
_DISTANCES: LRU[str, np.ndarray] = LRU(capacity=512)


def pair_tables(robot: RobotGeometry, budget_s: float = math.inf) -> tuple[np.ndarray, ...]:
    """Per pair (P,): its table's joints (P, 2) (−1: none), grid start (P, 2), step (P, 2),
    node count (P, 2), offset into the flat table (P,), motion bound per unit (P, 2); then the
    flat table of distances.

    Tables not yet in memory or on disk are built while `budget_s` lasts; a pair left without
    one is checked down its trees (slower, as sound), and a later call builds the rest."""
    packed = _TABLES.get(robot)
    if packed is None:
        packed, complete = _build(robot, time.perf_counter() + budget_s)
        if complete:
            _TABLES[robot] = packed
    return packed


def _build(robot: RobotGeometry, until: float) -> tuple[tuple[np.ndarray, ...], bool]:
    model = robot.model
    count = len(robot.pair_i)
    dofs = np.full((count, 2), -1, dtype=np.int64)
    start, step = np.zeros((count, 2)), np.ones((count, 2))
    nodes = np.ones((count, 2), dtype=np.int64)
    offset = np.zeros(count, dtype=np.int64)
    bound = np.zeros((count, 2))
    tables: list[np.ndarray] = []
    total = 0
    _, whole = robot.pair_motion()
    complete = True
    for p in range(count):
        moving = np.flatnonzero(robot.pair_mask[p])
        lo, hi = model.lower[moving], model.upper[moving]
        if not 1 <= len(moving) <= 2 or not np.all(np.isfinite(lo) & np.isfinite(hi)):
            continue
        sizes = [max(1, math.ceil((h - low) / STEP_RAD)) + 1 for low, h in zip(lo, hi, strict=True)]
        if math.prod(sizes) > MAX_NODES:
            continue
        axes = [np.linspace(low, h, n) for low, h, n in zip(lo, hi, sizes, strict=True)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(moving))
        distances = _cached_distances(robot, p, moving, grid, until)
        if distances is None:
            complete = False
            continue
        tables.append(distances)
        k = len(moving)
        dofs[p, :k] = moving
        start[p, :k] = lo
        step[p, :k] = [(h - low) / (n - 1) for low, h, n in zip(lo, hi, sizes, strict=True)]
        nodes[p, :k] = sizes
        offset[p] = total
        bound[p, :k] = whole[moving, p]
        total += len(grid)
    flat = np.concatenate(tables) if tables else np.zeros(0)
    return (dofs, start, step, nodes, offset, bound, np.ascontiguousarray(flat)), complete


def _cached_distances(
    robot: RobotGeometry, p: int, moving: np.ndarray, grid: np.ndarray, until: float
) -> np.ndarray | None:
    """The pair's distances, from memory or the disk cache (`geometry/disk_cache.py`), keyed
    by all they depend on: the kinematics, both elements' links, origins and shapes, the grid."""
    i, j = int(robot.pair_i[p]), int(robot.pair_j[p])
    content: list[object] = [STEP_RAD, HULL_ENOUGH_M, EXACT_MARGIN, moving, grid]
    content += [np.asarray(part) for part in fk_tables(robot.model)]
    for k in (i, j):
        element = robot.model.elements[k]
        shape = element.shape
        content += [int(element.link), element.origin, shape.kind.value]
        content += [np.asarray(shape.size, dtype=float)]
        if shape.vertices is not None and shape.faces is not None:
            content += [np.asarray(shape.vertices, float), np.asarray(shape.faces, np.int64)]
    key = digest(content)
    hit = _DISTANCES.get(key)
    if hit is None:
        arrays = cached_arrays(
            "pair-tables",
            key,
            lambda: {"distance": _distances(robot, p, moving, grid)},
            build_if=lambda: time.perf_counter() < until,
        )
        if arrays is None:
            return None
        hit = _DISTANCES.put(key, arrays["distance"])
    return hit


def _distances(robot: RobotGeometry, p: int, moving: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """coal's distance between the pair's elements at every grid node, less the margin."""
    model = robot.model
    base = np.zeros(model.dof)
    bounded = np.isfinite(model.lower) & np.isfinite(model.upper)
    base[bounded] = (model.lower[bounded] + model.upper[bounded]) / 2.0
    states = np.repeat(base[None], len(grid), axis=0)
    states[:, moving] = grid
    poses = element_transforms(model, forward_kinematics(model, states))
    i, j = int(robot.pair_i[p]), int(robot.pair_j[p])
    exact, hull = robot.exact.exact, robot.exact.hull
    request = coal.DistanceRequest()
    out = np.empty(len(grid))
    for n in range(len(grid)):
        a, b = poses[n, i], poses[n, j]
        placed_a = coal.Transform3s(a[:3, :3], a[:3, 3])
        placed_b = coal.Transform3s(b[:3, :3], b[:3, 3])
        # The hulls hold the elements, so their distance is a lower bound: kept where it is
        # large enough to prove the pair apart near this node, measured exactly elsewhere.
        out[n] = coal.distance(hull[i], placed_a, hull[j], placed_b, request, coal.DistanceResult())
        if out[n] < HULL_ENOUGH_M:
            out[n] = coal.distance(
                exact[i], placed_a, exact[j], placed_b, request, coal.DistanceResult()
            )
    return out - EXACT_MARGIN
