"""Self-collision pairs proven never to collide within the joint limits, so never checked.

The distance between two elements of the robot depends only on the dofs that move exactly one of
them (`RobotGeometry.pair_mask`): the dofs above both move them as one rigid body. When those are
few, the whole box of their values within the limits can be covered by cells, each certified
the way segments are (`validation/certify.py`): a lower bound d(c) on the distance at the cell's
centre c, and the configuration-independent bound M·h on how far any point of the pair moves
relative to the other from c to any state of the cell (h the cell's half widths), give

    d(q) ≥ d(c) − Σ_r h_r · M_r > 0  for every q in the cell, when d(c) > Σ_r h_r · M_r.

A cell the bound does not settle is split in two along each of its dofs and tried again, within a
budget of centres per pair; a pair is dropped only when every cell of its box is settled, and
kept as soon as a centre has no positive bound. The
lower bounds are the validator's own: support-function slabs, and coal's exact distance
(FCL's distances are never used). Revolute dofs without
limits span one turn.

This is the sampled "never in collision" rule of motion-planning setup tools made a proof: a
pair that can touch anywhere within the limits always keeps being checked. States outside the
limits are never checked for collisions (validation rejects them first).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.bodies import Posed, RobotGeometry, SceneGeometry
from trajcache.geometry.collision.clearance import Clearance
from trajcache.geometry.collision.narrow import Narrow
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import Scene

BoolArray = NDArray[np.bool_]

MAX_DOFS = 2  # pairs moved apart by more dofs keep being checked: their boxes are too large
CELL_RAD = 0.25  # widest first cell per dof (rad, or m for a prismatic dof)
MAX_CENTRES = 20_000  # bounds evaluated per pair before giving up on it
_ROUNDING = 1e-6  # what a proven distance must exceed


def proven_free_pairs(robot: RobotGeometry) -> BoolArray:
    """(P,) True for the pairs of `robot` that cannot collide anywhere within the limits."""
    free = np.zeros(len(robot.pair_i), dtype=bool)
    if len(free) == 0:
        return free
    scene = SceneGeometry(Scene(objects=()))
    clearance = Clearance(robot, scene)
    narrow = Narrow(robot, scene)
    _, whole = robot.pair_motion()  # (D, P)
    anc = robot.motion.ancestors
    for pair in range(len(free)):
        li, lj = robot.element_link[robot.pair_i[pair]], robot.element_link[robot.pair_j[pair]]
        dofs = np.flatnonzero((anc[li] | anc[lj]) & ~robot.motion.alike(li, lj))
        box = _box(robot, dofs)
        if box is not None and 0 < len(dofs) <= MAX_DOFS:
            free[pair] = _covered(robot, clearance, narrow, pair, dofs, box, whole[dofs, pair])
    return free


def _box(robot: RobotGeometry, dofs: NDArray[np.int64]) -> tuple[FloatArray, FloatArray] | None:
    """Lower and upper values of `dofs` within the limits (None: a dof without bounds)."""
    model = robot.model
    lower, upper = model.lower[dofs].copy(), model.upper[dofs].copy()
    for k, dof in enumerate(dofs):
        if not (math.isfinite(lower[k]) and math.isfinite(upper[k])):
            if not robot.motion.rotation[dof]:
                return None
            lower[k], upper[k] = -math.pi, math.pi
    return lower, upper


def _covered(
    robot: RobotGeometry,
    clearance: Clearance,
    narrow: Narrow,
    pair: int,
    dofs: NDArray[np.int64],
    box: tuple[FloatArray, FloatArray],
    motion: FloatArray,
) -> bool:
    """Whether cells certified at their centres cover the whole box of `dofs` for `pair`."""
    lower, upper = box
    counts = np.maximum(np.ceil((upper - lower) / CELL_RAD), 1).astype(np.int64)
    half = (upper - lower) / counts / 2.0
    axes = [lower[k] + half[k] * (2 * np.arange(counts[k]) + 1) for k in range(len(dofs))]
    centres = np.array(list(itertools.product(*axes)), dtype=float).reshape(-1, len(dofs))
    base = np.clip(0.0, robot.model.lower, robot.model.upper)  # any values: they move both alike
    spent = 0
    while len(centres):
        spent += len(centres)
        if spent > MAX_CENTRES:
            return False
        states = np.repeat(base[None], len(centres), axis=0)
        states[:, dofs] = centres
        bound = _lower_bound(robot, clearance, narrow, pair, states, float(half @ motion))
        if np.any(bound <= 0.0):
            return False  # touching, or too close to tell, at a state within the limits
        open_ = centres[bound <= half @ motion + _ROUNDING]
        half = half / 2.0
        offsets = np.array(list(itertools.product((-1.0, 1.0), repeat=len(dofs)))) * half
        centres = (open_[:, None, :] + offsets[None]).reshape(-1, len(dofs))
    return True


def _lower_bound(
    robot: RobotGeometry,
    clearance: Clearance,
    narrow: Narrow,
    pair: int,
    states: FloatArray,
    need: float,
) -> FloatArray:
    """A lower bound on the pair's distance at each state; the exact distance only where
    the cheaper slabs do not already exceed `need`."""
    posed = Posed.build(robot, states)
    rows = np.column_stack([np.arange(len(states)), np.full(len(states), pair)])
    bound = np.maximum(clearance.self_slabs(posed, rows), 0.0)
    weak = bound <= need + _ROUNDING
    if np.any(weak):
        bound[weak] = np.maximum(
            bound[weak], narrow.self_exact(posed, rows[weak], need + _ROUNDING)
        )
    return bound
