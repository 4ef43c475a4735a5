"""Per-model in-memory trajectory indexes, kept in step with the shared database.

Every replica keeps its own `TrajectoryIndex` per model. Before it answers a plan it reads what
other replicas wrote since it last looked: trajectory rows above its high-water mark, and
tombstones (deletions) above a second high-water mark.

Ids come from one sequence per table, and on PostgreSQL transactions can commit out of id
order: a row with a lower id may become visible after a higher one was read. So every id
skipped over is remembered as a gap and asked for again on each sync until it shows up or
`gap_ttl_s` passes (a rolled-back insert leaves a gap forever). Adding and removing are
idempotent, so reading a row twice is harmless.

One sync is one query: new and missing trajectory rows and tombstones are read together (UNION
ALL), so both come from the same snapshot. With `sync_interval_s=0` every plan needs a sync that
began after the plan arrived (so it sees every row committed before); requests that arrive while
a sync runs share the next one instead of queueing one each.

A plan's own first read (its robot and scene) can ride along as one more branch of that query
(`read_with_sync`): a cache hit then needs one round trip before lookup, not two. Both calls are
given the time the request arrived, so the `index` call that follows does not sync again.

Key states of candidates are kept in a byte-bounded LRU (`states`): a trajectory's states never
change after it is stored, and a deleted one leaves the cache with its tombstone.
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import InstrumentedAttribute, Session

from trajcache.cache.index import TrajectoryIndex
from trajcache.core.lru import LRU
from trajcache.db.models import Trajectory, TrajectoryTombstone, unpack_states
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray

if TYPE_CHECKING:
    from typing import TypeAlias

    AnySelect: TypeAlias = sa.Select[*tuple[Any, ...]]  # a select of any columns

_STARTUP_WINDOW = 10_000  # ids below the first high-water mark that may still be in flight
_MAX_GAPS = 100_000
_ROW, _TOMBSTONE, _RIDER = 0, 1, 2
_SYNC_COLUMNS = 6  # kind, id, model_id, start, goal, ref: a rider's columns follow them


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

    def __init__(
        self,
        *,
        sync_interval_s: float = 0.0,
        gap_ttl_s: float = 60.0,
        states_cache_bytes: int = 64 * 1024 * 1024,
    ) -> None:
        self.sync_interval_s = sync_interval_s
        self.gap_ttl_s = gap_ttl_s
        self.syncs = 0  # sync queries run (for tests and metrics)
        self._indexes: dict[str, TrajectoryIndex] = {}
        self._rows = IdStream()
        self._tombs = IdStream()
        self._started = False
        self._synced_from = -float("inf")  # when the last completed sync began (monotonic)
        self._lock = threading.Lock()
        self._states = StatesCache(states_cache_bytes)

    def clear_states(self) -> None:
        """Forget the cached key states (indexes stay: they are synchronised, not cached)."""
        self._states.clear()

    def index(
        self, session: Session, model: RobotModel, *, arrived: float | None = None
    ) -> TrajectoryIndex:
        """The model's index, after picking up what other replicas wrote before the request
        arrived (`time.monotonic()`; default now)."""
        asked = time.monotonic() if arrived is None else arrived
        with self._lock:
            if self._sync_due(asked):
                self._sync(session)
            index = self._indexes.get(model.model_id)
            if index is None:
                index = self._load_model(session, model)
            return index

    def read_with_sync(
        self, session: Session, rider: AnySelect, params: Mapping[str, Any], *, arrived: float
    ) -> tuple[Any, ...] | None:
        """The row of `rider` (a query of at most one row), read together with the sync that a
        request which arrived at `arrived` (`time.monotonic()`) needs: one query instead of two.

        `rider` is one more UNION ALL branch of the sync query (no ORDER BY or LIMIT of its own),
        so it reads the same snapshot. `index(..., arrived=arrived)` then needs no sync of its own.
        """
        with self._lock:
            if self._sync_due(arrived):
                return self._sync(session, rider, params)
        row = session.connection().execute(rider, params).one_or_none()
        return None if row is None else tuple(row)

    def states(self, session: Session, ids: Iterable[int]) -> dict[int, FloatArray]:
        """Key states (read-only arrays) of the trajectories `ids` that exist, by id."""
        found, missing = self._states.get_many(ids)
        if missing:
            rows = session.execute(
                sa.select(
                    Trajectory.id, Trajectory.states, Trajectory.n_states, Trajectory.dof
                ).where(Trajectory.id.in_(missing))
            ).all()
            for row in rows:
                states = unpack_states(row.states, n_states=row.n_states, dof=row.dof)
                states.flags.writeable = False
                found[int(row.id)] = self._states.put(int(row.id), states)
        return found

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

    def _sync_due(self, asked: float) -> bool:
        """Whether a request that arrived at `asked` needs a sync (call holding the lock)."""
        return not self._started or self._synced_from < asked - self.sync_interval_s

    def _sync(
        self,
        session: Session,
        rider: AnySelect | None = None,
        rider_params: Mapping[str, Any] | None = None,
    ) -> tuple[Any, ...] | None:
        began = time.monotonic()
        if not self._started:
            self._start(session, began)
        found = self._read_changes(session, began, rider, rider_params or {})
        self.syncs += 1
        self._synced_from = began
        return found

    def _read_changes(
        self,
        session: Session,
        now: float,
        rider: AnySelect | None,
        rider_params: Mapping[str, Any],
    ) -> tuple[Any, ...] | None:
        """New and missing rows and tombstones (and `rider`'s row) in one query; rows are
        applied first. Returns the row of `rider`, if any."""
        row_gaps = self._rows.wanted_gaps(now, self.gap_ttl_s)
        tomb_gaps = self._tombs.wanted_gaps(now, self.gap_ttl_s)
        params: dict[str, Any] = {"row_hwm": self._rows.hwm, "tomb_hwm": self._tombs.hwm}
        if row_gaps:
            params["row_gaps"] = row_gaps
        if tomb_gaps:
            params["tomb_gaps"] = tomb_gaps
        statement = _changes_statement(bool(row_gaps), bool(tomb_gaps), rider)
        if rider is not None:
            params.update(rider_params)
        changes = session.connection().execute(statement, params).all()
        new_rows = [c for c in changes if c.kind == _ROW]
        tombstones = [c for c in changes if c.kind == _TOMBSTONE]
        ridden = next((tuple(c)[_SYNC_COLUMNS:] for c in changes if c.kind == _RIDER), None)
        by_model: dict[str, list[Any]] = {}
        for row in new_rows:
            if row.model_id in self._indexes:
                by_model.setdefault(row.model_id, []).append(row)
        for model_id, model_rows in by_model.items():
            _add_rows(self._indexes[model_id], model_rows)
        for tomb in tombstones:
            self._states.discard(int(tomb.ref))
            index = self._indexes.get(tomb.model_id)
            if index is not None and tomb.ref in index:
                index.remove(np.array([tomb.ref], dtype=np.int64))
        self._rows.advance([int(r.id) for r in new_rows], now)
        self._tombs.advance([int(t.id) for t in tombstones], now)
        return ridden

    def _load_model(self, session: Session, model: RobotModel) -> TrajectoryIndex:
        rows = session.execute(
            sa.select(Trajectory.id, Trajectory.model_id, Trajectory.start, Trajectory.goal).where(
                Trajectory.model_id == model.model_id, Trajectory.id <= self._rows.hwm
            )
        ).all()
        index = TrajectoryIndex(model.dof, base=model.base)
        _add_rows(index, rows)
        self._indexes[model.model_id] = index
        return index


class StatesCache:
    """Thread-safe LRU of trajectory key states by id, bounded by their total size in bytes."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self._items: LRU[int, FloatArray] = LRU(max_size=max_bytes, size_fn=_nbytes)

    def get_many(self, ids: Iterable[int]) -> tuple[dict[int, FloatArray], list[int]]:
        """The cached states among `ids`, and the ids that are not cached."""
        return self._items.get_many(ids)

    def put(self, trajectory_id: int, states: FloatArray) -> FloatArray:
        """Cache `states` (unless larger than the whole budget) and return them."""
        return self._items.put(trajectory_id, states)

    def discard(self, trajectory_id: int) -> None:
        """Forget one trajectory's states."""
        self._items.discard(trajectory_id)

    def clear(self) -> None:
        """Forget every trajectory's states."""
        self._items.clear()

    def __len__(self) -> int:
        return len(self._items)


def _nbytes(states: FloatArray) -> int:
    return int(states.nbytes)


@functools.cache
def _changes_statement(
    row_gaps: bool, tomb_gaps: bool, rider: AnySelect | None = None
) -> sa.CompoundSelect[Any]:
    """Rows and tombstones above their high-water marks (`:row_hwm`, `:tomb_hwm`) or, when
    asked, among the gaps (`:row_gaps`, `:tomb_gaps`), and the row of `rider` if given (its
    columns after the sync's, null in the other branches); built once per shape and rider."""
    extra = list(rider.selected_columns) if rider is not None else []
    blanks = [sa.cast(sa.null(), c.type).label(f"rider_{i}") for i, c in enumerate(extra)]
    rows = sa.select(
        sa.literal_column(str(_ROW), sa.Integer).label("kind"),
        Trajectory.id.label("id"),
        Trajectory.model_id.label("model_id"),
        Trajectory.start.label("start"),
        Trajectory.goal.label("goal"),
        sa.cast(sa.null(), sa.BigInteger).label("ref"),
        *blanks,
    ).where(_above_or_in(Trajectory.id, "row", row_gaps))
    tombs = sa.select(
        sa.literal_column(str(_TOMBSTONE), sa.Integer),
        TrajectoryTombstone.id,
        TrajectoryTombstone.model_id,
        sa.cast(sa.null(), Trajectory.start.type),
        sa.cast(sa.null(), Trajectory.goal.type),
        TrajectoryTombstone.trajectory_id,
        *blanks,
    ).where(_above_or_in(TrajectoryTombstone.id, "tomb", tomb_gaps))
    if rider is None:
        return sa.union_all(rows, tombs)
    ridden = rider.with_only_columns(
        sa.literal_column(str(_RIDER), sa.Integer),
        sa.cast(sa.null(), sa.BigInteger),
        sa.cast(sa.null(), Trajectory.model_id.type),
        sa.cast(sa.null(), Trajectory.start.type),
        sa.cast(sa.null(), Trajectory.goal.type),
        sa.cast(sa.null(), sa.BigInteger),
        *extra,
        maintain_column_froms=True,
    )
    return sa.union_all(rows, tombs, ridden)


def _above_or_in(
    column: InstrumentedAttribute[int], name: str, gaps: bool
) -> sa.ColumnElement[bool]:
    above = column > sa.bindparam(f"{name}_hwm", type_=sa.BigInteger)
    if not gaps:
        return above
    return sa.or_(above, column.in_(sa.bindparam(f"{name}_gaps", expanding=True)))


def _add_rows(index: TrajectoryIndex, rows: Sequence[Any]) -> None:
    fresh = [r for r in rows if r.id not in index]
    if not fresh:
        return
    ids = np.array([r.id for r in fresh], dtype=np.int64)
    index.add(
        ids, np.array([r.start for r in fresh], float), np.array([r.goal for r in fresh], float)
    )
