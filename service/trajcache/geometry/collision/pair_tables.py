"""Distance tables of the self-collision pairs that only one or two joints move relative to each
other (a wrist's links against the forearm), for the compiled planner's state check.

Such a pair's distance d(q) depends on those joints' values only: every other joint moves both
elements alike (`RobotGeometry.pair_mask`). It is measured exactly (coal, less the narrow
phase's `EXACT_MARGIN`) at the nodes g of a grid over their limits. For any state q and the
nearest node g, moving from g to q along a straight line in those values moves any point of one
element relative to the other by at most Σ_d M_d |q_d − g_d|, with M_d the pair's
configuration-independent motion bound per unit of joint d (`RobotGeometry.pair_motion`, the
certification's). Distance is 1-Lipschitz in that motion, so

    d(q) ≥ d(g) − Σ_d M_d |q_d − g_d|,

and a positive right side proves the pair apart at q. A table is built once per model (variant)
and process, when a plan first needs it.
"""

from __future__ import annotations

import hashlib
import math
import weakref

import coal
import numpy as np

from trajcache.core.lru import LRU
from trajcache.geometry.collision.bodies import RobotGeometry
from trajcache.geometry.collision.narrow import EXACT_MARGIN
from trajcache.geometry.model.kinematics import element_transforms, fk_tables, forward_kinematics
from trajcache.geometry.model.shapes import Shape

STEP_RAD = 0.04  # grid step of a joint's values (metres for a prismatic joint)
MAX_NODES = 30_000  # a pair whose grid would be larger gets no table
_TABLES: weakref.WeakKeyDictionary[RobotGeometry, tuple[np.ndarray, ...]] = (
    weakref.WeakKeyDictionary()
)
# One pair's distances by what they depend on (model variants of one robot share them): the
# kinematic tables, the two elements' shapes and origins, and the grid.
_DISTANCES: LRU[tuple[object, ...], tuple[np.ndarray, tuple[Shape, Shape]]] = LRU(capacity=512)


def pair_tables(robot: RobotGeometry) -> tuple[np.ndarray, ...]:
    """Per pair (P,): its table's joints (P, 2) (−1: none), grid start (P, 2), step (P, 2),
    node count (P, 2), offset into the flat table (P,), motion bound per unit (P, 2); then the
    flat table of distances."""
    packed = _TABLES.get(robot)
    if packed is None:
        packed = _build(robot)
        _TABLES[robot] = packed
    return packed


def _build(robot: RobotGeometry) -> tuple[np.ndarray, ...]:
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
        tables.append(_cached_distances(robot, p, moving, grid))
        k = len(moving)
        dofs[p, :k] = moving
        start[p, :k] = lo
        step[p, :k] = [(h - low) / (n - 1) for low, h, n in zip(lo, hi, sizes, strict=True)]
        nodes[p, :k] = sizes
        offset[p] = total
        bound[p, :k] = whole[moving, p]
        total += len(grid)
    flat = np.concatenate(tables) if tables else np.zeros(0)
    return dofs, start, step, nodes, offset, bound, np.ascontiguousarray(flat)


def _cached_distances(
    robot: RobotGeometry, p: int, moving: np.ndarray, grid: np.ndarray
) -> np.ndarray:
    i, j = int(robot.pair_i[p]), int(robot.pair_j[p])
    elements = robot.model.elements
    key = (
        _kinematics_digest(robot),
        id(elements[i].shape),
        id(elements[j].shape),
        elements[i].origin.tobytes(),
        elements[j].origin.tobytes(),
        int(elements[i].link),
        int(elements[j].link),
        tuple(int(d) for d in moving),
        grid.tobytes(),
    )
    hit = _DISTANCES.get(key)
    if hit is None:
        hit = (_distances(robot, p, moving, grid), (elements[i].shape, elements[j].shape))
        _DISTANCES.put(key, hit)  # the shapes are kept with it: their ids stay theirs
    return hit[0]


def _kinematics_digest(robot: RobotGeometry) -> str:
    """A digest of the forward kinematics (joints, held values, base)."""
    digest = hashlib.sha256()
    for part in fk_tables(robot.model):
        digest.update(np.asarray(part).tobytes())
    return digest.hexdigest()


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
    body_i, body_j = robot.exact.exact[i], robot.exact.exact[j]
    request = coal.DistanceRequest()
    out = np.empty(len(grid))
    for n in range(len(grid)):
        a, b = poses[n, i], poses[n, j]
        out[n] = coal.distance(
            body_i, coal.Transform3s(a[:3, :3], a[:3, 3]),
            body_j, coal.Transform3s(b[:3, :3], b[:3, 3]),
            request, coal.DistanceResult(),
        )  # fmt: skip
    return out - EXACT_MARGIN
