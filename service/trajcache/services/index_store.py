"""Per-model in-memory trajectory indexes, kept in step with the shared database.

Every replica keeps its own `TrajectoryIndex` per model. Before it answers a plan it reads what
other replicas wrote since it last looked: trajectory rows above its high-water mark, and
tombstones (deletions) above a second high-water mark.

Ids come from one sequence per table, and on PostgreSQL transactions can commit out of id
order: a row with a lower id may become visible after a higher one was read. So every id
skipped over is remembered as a gap and asked for again on each sync until it shows up or
`gap_ttl_s` passes (a rolled-back insert leaves a gap forever). Adding and removing are
idempotent, so reading a row twice is harmless.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.cache.index import TrajectoryIndex
from trajcache.db.models import Trajectory, TrajectoryTombstone
from trajcache.geometry.robot import RobotModel

_STARTUP_WINDOW = 10_000  # ids below the first high-water mark that may still be in flight
_MAX_GAPS = 100_000


@dataclass
class IdStream:
    """How far one id sequence has been read, and which ids below that are still missing."""

    hwm: int = 0
    gaps: dict[int, float] = field(default_factory=dict)  # id -> when it was first missed

    def wanted_gaps(self, now: float, ttl_s: float) -> list[int]:
        """Gaps still worth asking for."""
        expired = [i for i, t in self.gaps.items() if now - t > ttl_s]
        for i in expired:
            del self.gaps[i]
        return list(self.gaps)

    def advance(self, seen: list[int], now: float) -> None:
        """Record ids just read; ids skipped over become gaps."""
        for i in seen:
            self.gaps.pop(i, None)
        top = max(seen, default=self.hwm)
        if top > self.hwm:
            present = set(seen)
            missing = [i for i in range(self.hwm + 1, top) if i not in present]
            for i in missing[-_MAX_GAPS:]:
                self.gaps[i] = now
            self.hwm = top


class IndexStore:
    """All models' indexes of one service process, synchronised through the database."""

    def __init__(self, *, sync_interval_s: float = 0.0, gap_ttl_s: float = 60.0) -> None:
        self.sync_interval_s = sync_interval_s
        self.gap_ttl_s = gap_ttl_s
        self._indexes: dict[str, TrajectoryIndex] = {}
        self._rows = IdStream()
        self._tombs = IdStream()
        self._started = False
        self._last_sync = -1e18
        self._lock = threading.Lock()

    def index(self, session: Session, model: RobotModel) -> TrajectoryIndex:
        """The model's index, after picking up what other replicas wrote."""
        with self._lock:
            now = time.monotonic()
            if not self._started or now - self._last_sync >= self.sync_interval_s:
                self._sync(session, now)
            index = self._indexes.get(model.model_id)
            if index is None:
                index = self._load_model(session, model)
            return index

    def sync(self, session: Session) -> None:
        """Read new rows and tombstones now."""
        with self._lock:
            self._sync(session, time.monotonic())

    def sizes(self) -> dict[str, int]:
        """Number of indexed trajectories per loaded model."""
        with self._lock:
            return {m: len(i) for m, i in self._indexes.items()}

    def _start(self, session: Session, now: float) -> None:
        for stream, column in ((self._rows, Trajectory.id), (self._tombs, TrajectoryTombstone.id)):
            top = session.execute(sa.select(sa.func.max(column))).scalar() or 0
            floor = max(0, top - _STARTUP_WINDOW)
            seen = session.execute(sa.select(column).where(column > floor)).scalars().all()
            stream.hwm = floor
            stream.advance([int(i) for i in seen], now)
            stream.hwm = max(stream.hwm, int(top))
        self._started = True

    def _sync(self, session: Session, now: float) -> None:
        if not self._started:
            self._start(session, now)
        self._read_tombstones(session, now)
        self._read_rows(session, now)
        self._last_sync = now

    def _read_rows(self, session: Session, now: float) -> None:
        stream = self._rows
        cond = Trajectory.id > stream.hwm
        gaps = stream.wanted_gaps(now, self.gap_ttl_s)
        if gaps:
            cond = sa.or_(cond, Trajectory.id.in_(gaps))
        rows = session.execute(
            sa.select(Trajectory.id, Trajectory.model_id, Trajectory.start, Trajectory.goal).where(
                cond
            )
        ).all()
        by_model: dict[str, list[Any]] = {}
        for row in rows:
            if row.model_id in self._indexes:
                by_model.setdefault(row.model_id, []).append(row)
        for model_id, model_rows in by_model.items():
            _add_rows(self._indexes[model_id], model_rows)
        stream.advance([int(r.id) for r in rows], now)

    def _read_tombstones(self, session: Session, now: float) -> None:
        stream = self._tombs
        cond = TrajectoryTombstone.id > stream.hwm
        gaps = stream.wanted_gaps(now, self.gap_ttl_s)
        if gaps:
            cond = sa.or_(cond, TrajectoryTombstone.id.in_(gaps))
        rows = session.execute(
            sa.select(
                TrajectoryTombstone.id,
                TrajectoryTombstone.model_id,
                TrajectoryTombstone.trajectory_id,
            ).where(cond)
        ).all()
        for row in rows:
            index = self._indexes.get(row.model_id)
            if index is not None and row.trajectory_id in index:
                index.remove(np.array([row.trajectory_id], dtype=np.int64))
        stream.advance([int(r.id) for r in rows], now)

    def _load_model(self, session: Session, model: RobotModel) -> TrajectoryIndex:
        rows = session.execute(
            sa.select(Trajectory.id, Trajectory.model_id, Trajectory.start, Trajectory.goal).where(
                Trajectory.model_id == model.model_id, Trajectory.id <= self._rows.hwm
            )
        ).all()
        index = TrajectoryIndex(model.dof, arm_offset=model.arm_offset)
        _add_rows(index, rows)
        self._indexes[model.model_id] = index
        return index


def _add_rows(index: TrajectoryIndex, rows: Sequence[Any]) -> None:
    fresh = [r for r in rows if r.id not in index]
    if not fresh:
        return
    ids = np.array([r.id for r in fresh], dtype=np.int64)
    index.add(
        ids, np.array([r.start for r in fresh], float), np.array([r.goal for r in fresh], float)
    )
