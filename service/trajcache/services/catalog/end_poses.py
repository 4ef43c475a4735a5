"""The end-pose index: the poses of each stored trajectory's ends, written with the trajectory.

Every store writes the index rows of a new trajectory in the transaction that inserts it
(`store_trajectory`, and the batched import through `bulk_insert`): for each indexed link
(`geometry.model.end_poses.indexed_anchors`: the anchors of the model's tips) its pose at the
start state and at the goal state, relative to the root link. Trajectories stored before the
index existed are in `end_pose_backlog` (migration 0016) until the background backfill writes
theirs (`services.maintenance.backfill`). Rows are deleted with their trajectory (a delete or
an eviction: the foreign key cascades) and with their model.

A lookup (`ends_near`) reads the rows of one link within a radius of a position, nearest
first, and optionally within an orientation tolerance (|q·q*| ≥ cos(tol/2)), with the states
of the ends they belong to; the database does the search, so it costs the same for a cache of
a hundred trajectories as for a hundred thousand and sees every one of them.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sqlalchemy as sa
from scipy.spatial.transform import Rotation
from sqlalchemy.orm import Session

from trajcache.db import models as tables
from trajcache.db.end_poses import TrajectoryEndPose
from trajcache.geometry.model.end_poses import indexed_anchors, root_relative
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray

__all__ = ["EndsNear", "ends_near", "index_links", "write_end_poses"]

_E = TrajectoryEndPose
_POSE = ("x", "y", "z", "qx", "qy", "qz", "qw")
_LINKS: weakref.WeakKeyDictionary[RobotModel, tuple[str, ...]] = weakref.WeakKeyDictionary()


def index_links(session: Session, model: RobotModel) -> tuple[str, ...]:
    """The links model `model` indexes (read once per loaded model: its SRDF never changes)."""
    links = _LINKS.get(model)
    if links is None:
        config = session.scalar(
            sa.select(tables.RobotModel.config).where(tables.RobotModel.id == model.model_id)
        )
        links = indexed_anchors(model, (config or {}).get("srdf"))
        _LINKS[model] = links
    return links


def write_end_poses(
    session: Session, model: RobotModel, ids: Sequence[int], starts: FloatArray, goals: FloatArray
) -> int:
    """Insert the index rows of the trajectories `ids` (their start and goal states, in
    order) in the session's transaction; how many rows."""
    links = index_links(session, model)
    if not links or not ids:
        return 0
    states = np.concatenate([np.asarray(starts, float), np.asarray(goals, float)])
    columns = [model.link_names.index(link) for link in links]
    poses = root_relative(model, states, columns).reshape(2, len(ids), len(links), 7)
    rows = [
        {
            "trajectory_id": int(tid),
            "model_id": model.model_id,
            "link": link,
            "end": end,
            **dict(zip(_POSE, map(float, poses[end, i, k]), strict=True)),
        }
        for end in (0, 1)
        for i, tid in enumerate(ids)
        for k, link in enumerate(links)
    ]
    session.execute(sa.insert(_E), rows)
    return len(rows)


@dataclass(frozen=True)
class EndsNear:
    """Cached trajectory ends whose link is near a pose, nearest first: the end states, the
    other end of each one's trajectory, and the link's distance from the position."""

    states: FloatArray  # (n, D)
    partners: FloatArray  # (n, D)
    gaps: FloatArray  # (n,) m


def ends_near(
    session: Session,
    model_id: str,
    link: str,
    pose: FloatArray,
    *,
    radius: float | None,
    orientation_tolerance: float | None = None,
    limit: int,
) -> EndsNear:
    """The ends (at most `limit`) whose `link` lies within `radius` of `pose`'s position (None:
    anywhere) and, given a tolerance, whose orientation is within it, nearest first and then
    the best oriented; `pose` is a 4×4 transform relative to the root link."""
    x, y, z = (float(v) for v in pose[:3, 3])
    gap2 = (_E.x - x) * (_E.x - x) + (_E.y - y) * (_E.y - y) + (_E.z - z) * (_E.z - z)
    qx, qy, qz, qw = _quaternion(pose)
    dot = sa.func.abs(_E.qx * qx + _E.qy * qy + _E.qz * qz + _E.qw * qw)
    conditions = [_E.model_id == model_id, _E.link == link]
    if radius is not None:
        conditions += [_E.x.between(x - radius, x + radius), gap2 <= radius * radius]
        conditions += [_E.y.between(y - radius, y + radius), _E.z.between(z - radius, z + radius)]
    if orientation_tolerance is not None and orientation_tolerance < math.pi:
        conditions.append(dot >= math.cos(orientation_tolerance / 2.0))
    T = tables.Trajectory
    rows = session.execute(
        sa.select(_E.end, gap2, T.start, T.goal)
        .join(T, T.id == _E.trajectory_id)
        .where(*conditions)
        .order_by(gap2, dot.desc(), _E.id)
        .limit(limit)
    ).all()
    if not rows:
        return EndsNear(np.empty((0, 0)), np.empty((0, 0)), np.empty(0))
    ends = [(r.goal, r.start) if r.end else (r.start, r.goal) for r in rows]
    return EndsNear(
        np.array([e[0] for e in ends], dtype=float),
        np.array([e[1] for e in ends], dtype=float),
        np.sqrt(np.maximum(np.array([r[1] for r in rows], dtype=float), 0.0)),
    )


def _quaternion(pose: FloatArray) -> tuple[float, float, float, float]:
    """The unit quaternion (x, y, z, w) of a 4×4 transform's rotation."""
    qx, qy, qz, qw = Rotation.from_matrix(pose[:3, :3]).as_quat()
    return float(qx), float(qy), float(qz), float(qw)
