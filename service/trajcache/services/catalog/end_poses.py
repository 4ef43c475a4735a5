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
of the ends they belong to. The database does the search on a covering index: its cost grows
with the ends in a slab around the position, not with the whole cache, and it sees them all.
"""

from __future__ import annotations

import functools
import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db import models as tables
from trajcache.db.bulk import insert_rows
from trajcache.db.end_poses import TrajectoryEndPose
from trajcache.geometry.model.end_poses import indexed_anchors, root_relative
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray

__all__ = ["EndsNear", "ends_near", "index_links", "write_end_poses"]

_E = TrajectoryEndPose
_TABLE: sa.Table = _E.__table__  # type: ignore[assignment]
_POSE = ("x", "y", "z", "qx", "qy", "qz", "qw")
_COLUMNS = ("trajectory_id", "model_id", "link", "end", *_POSE)
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
    values = poses.tolist()  # Python floats, as the driver writes them
    rows = [
        (int(tid), model.model_id, link, end, *values[end][i][k])
        for end in (0, 1)
        for i, tid in enumerate(ids)
        for k, link in enumerate(links)
    ]
    insert_rows(session, _TABLE, _COLUMNS, rows)
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
    radius: float,
    orientation_tolerance: float | None = None,
    limit: int,
) -> EndsNear:
    """The ends (at most `limit`) whose `link` lies within `radius` of `pose`'s position and,
    given a tolerance, whose orientation is within it, nearest first and then the best
    oriented; `pose` is a 4×4 transform relative to the root link."""
    x, y, z = (float(v) for v in pose[:3, 3])
    qx, qy, qz, qw = (float(v) for v in pin.Quaternion(pose[:3, :3]).coeffs())
    cos_min = -1.0  # |q·q*| ≥ cos(tolerance / 2): the rotation between them within it
    if orientation_tolerance is not None:
        cos_min = math.cos(min(orientation_tolerance, math.pi) / 2.0)
    params = {"model_id": model_id, "link": link, "x": x, "y": y, "z": z, "r": radius}
    params |= {"qx": qx, "qy": qy, "qz": qz, "qw": qw, "cos_min": cos_min, "limit": limit}
    statement = _ends_near_statement(orientation_tolerance is not None)
    rows = session.connection().execute(statement, params).all()  # core rows: no ORM overhead
    if not rows:
        return EndsNear(np.empty((0, 0)), np.empty((0, 0)), np.empty(0))
    ends = [(r.goal, r.start) if r.end else (r.start, r.goal) for r in rows]
    return EndsNear(
        np.array([e[0] for e in ends], dtype=float),
        np.array([e[1] for e in ends], dtype=float),
        np.sqrt(np.maximum(np.array([r.gap2 for r in rows], dtype=float), 0.0)),
    )


@functools.cache
def _ends_near_statement(oriented: bool) -> sa.Select[Any]:
    """`ends_near`'s query, built once: the index rows in the box around the position, within
    the radius (and the orientation), nearest first; then the trajectories of those only. By
    position alone, the index is read without its table."""
    p = sa.bindparam
    x, y, z, r = (p(name, type_=sa.Float) for name in ("x", "y", "z", "r"))
    gap2 = (_E.x - x) * (_E.x - x) + (_E.y - y) * (_E.y - y) + (_E.z - z) * (_E.z - z)
    conditions = [_E.model_id == p("model_id"), _E.link == p("link")]
    conditions += [_E.x.between(x - r, x + r), _E.y.between(y - r, y + r)]
    conditions += [_E.z.between(z - r, z + r), gap2 <= r * r]
    ranked: sa.ColumnElement[Any] = sa.literal(1.0)
    if oriented:
        qx, qy, qz, qw = (p(name, type_=sa.Float) for name in ("qx", "qy", "qz", "qw"))
        ranked = sa.func.abs(_E.qx * qx + _E.qy * qy + _E.qz * qz + _E.qw * qw)
        conditions.append(ranked >= p("cos_min", type_=sa.Float))
    nearest = (
        sa.select(_E.id, _E.trajectory_id, _E.end, gap2.label("gap2"), ranked.label("dot"))
        .where(*conditions)
        .order_by(gap2, ranked.desc(), _E.id)
        .limit(p("limit", type_=sa.Integer))
        .subquery()
    )
    T = tables.Trajectory
    return (
        sa.select(nearest.c.end, nearest.c.gap2, T.start, T.goal)
        .join(T, T.id == nearest.c.trajectory_id)
        .order_by(nearest.c.gap2, nearest.c.dot.desc(), nearest.c.id)
    )
