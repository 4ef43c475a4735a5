"""Quality of imported trajectories, computed in the background, throttled, across restarts.

An import writes its rows with `quality_pending` set and no quality (`importer`). Every service
process runs a `QualityBackfill` thread that picks pending rows a batch at a time, computes
their quality (path lengths, clearance in their stored scene, time-optimal duration) under the
app's settings, and clears the mark. Since the mark is in the database, work an import left
(or a process stopped in the middle of) is picked up at the next start, by any replica.

Throttling: at most `quality_backfill_per_s` rows a second (0 turns the thread off), in batches
of at most one second's worth, with the thread asleep between them, so the computation takes a
bounded share of one core and request threads keep the interpreter most of the time. On
PostgreSQL replicas skip rows another one is working on (`FOR UPDATE SKIP LOCKED`); elsewhere
two replicas may compute the same row twice, harmlessly (same settings, same answer).

The same thread indexes the end poses of trajectories stored before the end-pose index existed
(`end_pose_backlog`, filled by migration 0016; `index_backlog_batch`): a backlog entry's index
rows are written and the entry deleted in one transaction, so a trajectory is indexed once.
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db import models as tables
from trajcache.db.end_poses import EndPoseBacklog, TrajectoryEndPose
from trajcache.services.catalog.end_poses import write_end_poses
from trajcache.services.catalog.models import get_model
from trajcache.services.catalog.trajectories import quality_columns, scene_with_hash
from trajcache.services.context import ServiceContext
from trajcache.services.errors import NotFoundError
from trajcache.services.maintenance.loop import BackgroundLoop

_log = logging.getLogger(__name__)
_T = tables.Trajectory
IDLE_POLL_S = 5.0  # between looks for pending rows when none were found
MAX_BATCH = 200
_EMPTY = {"length": None, "ee_length": None, "min_clearance": None, "duration_s": None}


def pending_count(session: Session) -> int:
    """How many trajectories still wait for their quality."""
    query = sa.select(sa.func.count()).select_from(_T).where(_T.quality_pending.is_(True))
    return int(session.scalar(query) or 0)


def backfill_batch(ctx: ServiceContext, limit: int) -> int:
    """Compute and store the quality of up to `limit` pending rows; how many were done."""
    with ctx.sessions() as session:
        rows = session.scalars(
            sa.select(_T)
            .where(_T.quality_pending.is_(True))
            .order_by(_T.id)
            .limit(limit)
            .with_for_update(skip_locked=True)
        ).all()
        for row in rows:
            values = _quality(ctx, session, row)
            for name, value in {**_EMPTY, "quality": None, **(values or {})}.items():
                setattr(row, name, value)
            row.quality_pending = False
        session.commit()
        return len(rows)


def index_backlog_batch(ctx: ServiceContext, limit: int) -> int:
    """Write the end poses of up to `limit` backlog trajectories; how many were done."""
    _B = EndPoseBacklog
    with ctx.sessions() as session:
        rows = session.execute(
            sa.select(_T.id, _T.model_id, _T.start, _T.goal)
            .join(_B, _B.trajectory_id == _T.id)
            .order_by(_T.id)
            .limit(limit)
            .with_for_update(of=_B, skip_locked=True)
        ).all()
        ids = [row.id for row in rows]
        session.execute(
            sa.delete(TrajectoryEndPose).where(TrajectoryEndPose.trajectory_id.in_(ids))
        )
        for model_id in {row.model_id for row in rows}:
            mine = [row for row in rows if row.model_id == model_id]
            model = get_model(session=session, registry=ctx.models, model_id=model_id)
            starts = np.array([row.start for row in mine], dtype=float)
            goals = np.array([row.goal for row in mine], dtype=float)
            write_end_poses(session, model, [row.id for row in mine], starts, goals)
        session.execute(sa.delete(_B).where(_B.trajectory_id.in_(ids)))
        session.commit()
        return len(rows)


def _quality(ctx: ServiceContext, session: Session, row: tables.Trajectory) -> dict | None:
    """The row's quality columns; None when they cannot be computed (the mark is cleared
    anyway: a metric that cannot be computed is left empty, as at store time)."""
    try:
        model = get_model(session=session, registry=ctx.models, model_id=row.model_id)
    except NotFoundError:
        return None
    scene = None
    if row.scene_hash is not None:
        scene = scene_with_hash(session, row.scene_hash, ctx.scenes)
    return quality_columns(
        model, row.states_array(), ctx.settings, scene, validators=ctx.validators
    )


class QualityBackfill(BackgroundLoop):
    """The background thread of one service process (see the module docstring); it looks for
    pending rows at once (work left before a restart)."""

    thread_name = "quality-backfill"
    step_name = "background quality"

    def __init__(self, ctx: ServiceContext) -> None:
        super().__init__(ctx)
        self.done = 0
        self._rate = ctx.settings.quality_backfill_per_s

    def first_pause_s(self) -> float:
        return 0.0

    def step(self) -> float:
        started = time.monotonic()
        batch = batch_size(self._rate)
        done = backfill_batch(self.ctx, batch) + index_backlog_batch(self.ctx, batch)
        self.done += done
        return pause_after(done, self._rate, time.monotonic() - started)

    def failure_pause_s(self) -> float:
        return pause_after(0, self._rate, 0.0)


def batch_size(rate: float) -> int:
    """Rows per batch at `rate` rows a second: a second's worth, at most MAX_BATCH."""
    return max(1, min(MAX_BATCH, math.ceil(rate)))


def pause_after(done: int, rate: float, elapsed_s: float) -> float:
    """The rest after a batch of `done` rows that took `elapsed_s`: `done` rows may take
    done / rate seconds in all; none were pending: look again after IDLE_POLL_S."""
    return max(done / rate - elapsed_s, 0.0) if done else IDLE_POLL_S
