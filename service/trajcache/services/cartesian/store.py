"""The cache of Cartesian paths: whole answers stored, near repeats served after certification.

A path is stored only when it reached fraction 1.0, in one transaction. A later request is a
candidate for a stored path when it names the same model and link, its parameters have the same
digest (the steps, thresholds and IK tolerances: `params_digest`), its start is within
`joint_tolerance` of the stored start (every value), and it has as many waypoints, each within
`position_tolerance` (m) and `orientation_tolerance` (rad) of the stored one. Candidates are
tried nearest first (the start's largest gap plus the waypoints', a ranking only), at most
TRIED of them among the CANDIDATES most recent: the stored joint path with its first state
replaced by the request's start is served only when it is a complete path of its own request
(its stored start and waypoints, the request's parameters, which the digest matched:
`planning.cartesian.path_fault`: every state solves its sample within the IK tolerances, no
jump over the thresholds) and the request's validator (certified, in the robot's current scene,
as a computed path is) finds every joint motion valid. Never served on a stored row's word (an
imported one's included) nor uncertified; a scene change that blocks the path makes the request
compute anew.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation
from sqlalchemy import select

from trajcache.db.cartesian import CartesianPathRow
from trajcache.geometry.model.shapes import FloatArray
from trajcache.planning.cartesian import (
    CartesianPath,
    CartesianProblem,
    CartesianStatus,
    path_fault,
    sample_lines,
)
from trajcache.services.context import ServiceContext

__all__ = ["CacheQuery", "CachedPath", "lookup_path", "params_digest", "store_path"]

CANDIDATES = 64  # the most recent stored paths of the model, link and parameters compared
TRIED = 3  # of the near ones, the most certified before computing anew


@dataclass(frozen=True)
class CacheQuery:
    """Whether to look up and store, and how near a stored path must be to serve."""

    lookup: bool = True
    store: bool = True
    joint_tolerance: float = 1e-3  # rad or m, every value of the start
    position_tolerance: float = 1e-3  # m, each waypoint
    orientation_tolerance: float = 1e-2  # rad, each waypoint


@dataclass(frozen=True)
class CachedPath:
    """A stored path served for a request: certified, its start the request's."""

    path: CartesianPath
    path_id: int


def params_digest(problem: CartesianProblem) -> str:
    """A digest of every parameter a stored path's states depend on besides the model, the
    link, the start and the waypoints."""
    values = [
        problem.max_step,
        problem.max_rotation_step,
        problem.jump_threshold,
        problem.revolute_jump_threshold,
        problem.prismatic_jump_threshold,
        problem.position_tolerance,
        problem.orientation_tolerance,
    ]
    return hashlib.sha256(json.dumps([repr(float(v)) for v in values]).encode()).hexdigest()


def _waypoint_rows(problem: CartesianProblem) -> FloatArray:
    """Each waypoint as [x, y, z, qx, qy, qz, qw]."""
    poses = np.array(problem.waypoints, dtype=float)
    quats = Rotation.from_matrix(poses[:, :3, :3]).as_quat()
    return np.hstack([poses[:, :3, 3], quats])


def store_path(
    ctx: ServiceContext, model_id: str, problem: CartesianProblem, path: CartesianPath
) -> int:
    """Store a whole path (fraction 1.0) in one transaction; its id."""
    row = CartesianPathRow(
        model_id=model_id,
        link=problem.link,
        params=params_digest(problem),
        waypoints=_waypoint_rows(problem).tolist(),
        start=np.asarray(problem.start, dtype=float).tolist(),
        states=np.asarray(path.states, dtype=float).tolist(),
        line_of=[int(k) for k in path.line_of],
    )
    with ctx.sessions.begin() as session:
        session.add(row)
        session.flush()
        return int(row.id)


def lookup_path(
    ctx: ServiceContext, model_id: str, problem: CartesianProblem, query: CacheQuery
) -> CachedPath | None:
    """The nearest stored path that serves `problem`, certified (module docstring), or None."""
    statement = (
        select(CartesianPathRow)
        .where(
            CartesianPathRow.model_id == model_id,
            CartesianPathRow.link == problem.link,
            CartesianPathRow.params == params_digest(problem),
        )
        .order_by(CartesianPathRow.id.desc())
        .limit(CANDIDATES)
    )
    with ctx.sessions() as session:
        found = session.scalars(statement)
        rows = [(r.id, r.start, r.waypoints, r.states, r.line_of) for r in found]
    start = np.asarray(problem.start, dtype=float)
    wanted = _waypoint_rows(problem)
    near = []
    for path_id, stored_start, waypoints, states, line_of in rows:
        if len(stored_start) != len(start):
            continue
        gap = np.abs(np.asarray(stored_start) - start)
        if gap.max() <= query.joint_tolerance and _waypoints_near(
            np.asarray(waypoints), wanted, query
        ):
            offset = np.linalg.norm(np.asarray(waypoints)[:, :3] - wanted[:, :3], axis=1).max()
            near.append(
                (float(gap.max() + offset), path_id, stored_start, waypoints, states, line_of)
            )
    near.sort(key=lambda entry: entry[0])
    for _, path_id, stored_start, waypoints, states, line_of in near[:TRIED]:
        if _stored_fault(problem, stored_start, waypoints, states, line_of):
            continue
        served = np.array(states, dtype=float)
        served[0] = start
        if problem.validate_fn is not None and problem.validate_fn(served).kept < len(served):
            continue
        return CachedPath(_served(problem, served, np.asarray(line_of)), int(path_id))
    return None


def _stored_fault(
    problem: CartesianProblem,
    start: list[float],
    waypoints: list[list[float]],
    states: list[list[float]],
    line_of: list[int],
) -> str:
    """Why a stored path is not a complete path of its own request under `problem`'s
    parameters (empty: it is one)."""
    rows = np.asarray(waypoints, dtype=float)
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    poses[:, :3, :3] = Rotation.from_quat(rows[:, 3:]).as_matrix()  # a unit, whatever stored
    poses[:, :3, 3] = rows[:, :3]
    own = replace(problem, start=np.asarray(start, dtype=float), waypoints=list(poses))
    return path_fault(own, np.asarray(states, dtype=float), np.asarray(line_of))


def _waypoints_near(stored: FloatArray, wanted: FloatArray, query: CacheQuery) -> bool:
    if stored.shape != wanted.shape:
        return False
    if np.linalg.norm(stored[:, :3] - wanted[:, :3], axis=1).max() > query.position_tolerance:
        return False
    turn = Rotation.from_quat(stored[:, 3:]).inv() * Rotation.from_quat(wanted[:, 3:])
    return bool(turn.magnitude().max() <= query.orientation_tolerance)


def _served(problem: CartesianProblem, states: FloatArray, line_of: np.ndarray) -> CartesianPath:
    """The stored path as the answer to `problem`: its lines are the request's."""
    kin = problem.kinematics
    origin = kin.link_pose(states[0], kin.frame_id(problem.link))
    lines = sample_lines(origin, problem.waypoints, problem.max_step, problem.max_rotation_step)[3]
    return CartesianPath(CartesianStatus.COMPLETE, states, 1.0, lines, line_of.astype(np.int64))
