"""Per-model in-memory trajectory indexes, kept in step with the shared database.

Every replica keeps its own `TrajectoryIndex` per model. Before it answers a plan it reads what
other replicas wrote since it last looked: the rows of the trajectory commit log above its
high-water mark, each joined to the trajectories of its id range, and tombstones (deletions)
above a second high-water mark. Every transaction that inserts trajectories logs the range of
each write (`db.commit_log`: `store_trajectory` one id, an import one range per batch), in the
same transaction, as its last writes before the commit.

The sync never walks trajectory ids: an import holding 100,000 uncommitted rows in one long
transaction leaves only its few log rows in the log's index, and those only in its last moment.
(Reading `trajectories.id > mark` walked every uncommitted row above the mark and checked each
one's visibility, on every sync.)

Ids come from one sequence per table, and on PostgreSQL transactions can commit out of id
order: a log row with a lower id may become visible after a higher one was read. So every log id
skipped over is remembered as a gap and asked for again on each sync until it shows up or
`gap_ttl_s` passes (a rolled-back write leaves a gap forever). Adding and removing are
idempotent, so reading a row twice is harmless.

Why no committed trajectory is missed. A model's index is loaded (`_load_model`) with every row
of the model committed when the load reads. A trajectory committed later was logged in its own
transaction, so its log row became visible with it, after the load; that log id is either above
the high-water mark, or below it and then a gap (the mark passed it while it was not visible:
`IdStream.advance` marks every id skipped over), or it was read before it committed, which
cannot be. It is missed only if its log row waited longer than `gap_ttl_s` between taking its id
and committing (log rows are the last writes, so this is the commit's own latency), or lies more
than `_STARTUP_WINDOW` ids below the first mark of a replica started while it was in flight.
A replica started while writers are active takes as its mark the highest visible log id, with
the invisible ids of the window below it as gaps, and loads each model later: whatever commits
after the load is above the mark or a gap. A log row pruned before this replica read it
(`commit_log_retention_s`, far above `gap_ttl_s`) is noticed: pruning deletes a prefix of the
log and keeps its newest row, so the oldest id left (read in the same query) then lies above
the mark + 1, and the replica starts over, loading its indexes again (`_reload`).

Why nothing is read that should not be. A log row joins the trajectories of its range as they
are now: rows of other transactions inside the range are committed ones (they have log rows of
their own; adding is idempotent) and an uncommitted one is invisible; a rolled-back write has no
visible log row and no rows. A deleted trajectory is not in the table, so a log row read after
the deletion adds nothing (the outer join still yields the log row, so it advances the mark and
does not stay a gap); a deletion that commits after a row was added comes as a tombstone, and
tombstones are applied after rows in the same sync. A load and a sync read different snapshots,
but each only adds what is committed and each deletion has a tombstone read after it commits.
Tombstones are pruned as the log is (`db.commit_log.prune_tombstones`, the same retention), and a
tombstone pruned before this replica read it is noticed the same way: the oldest tombstone id
left lies above the tombstones' mark + 1, and the replica reloads.

One sync is one query: new and missing log rows with their trajectories, tombstones and the
oldest log id are read together (UNION ALL), so they come from the same snapshot. With
`sync_interval_s=0` every plan needs a sync that began after the plan arrived (so it sees every
row committed before); requests that arrive while a sync runs share the next one instead of
queueing one each.

A plan's own first read (its robot and scene) can ride along as one more branch of that query
(`read_with_sync`): a cache hit then needs one round trip before lookup, not two. Both calls are
given the time the request arrived, so the `index` call that follows does not sync again.

A trajectory this replica stores is indexed after its commit (`add_stored`), its log id marked
read (`advance`: ids skipped become gaps), so its first hit needs no sync to read it back. Under
the sync's lock, and only if no sync read its log row yet: one that did has added it and perhaps
applied its tombstone, which adding it again would undo. If none did, none read a tombstone of
it either: a deletion commits after the insert, and a query that saw the tombstone saw the row.

Key states of candidates are kept in a byte-bounded LRU (`states`): a trajectory's states never
change after it is stored, and a deleted one leaves the cache with its tombstone.
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import InstrumentedAttribute

from trajcache.cache.index import TrajectoryIndex
from trajcache.db.models import Trajectory, TrajectoryCommit, TrajectoryTombstone, unpack_states
from trajcache.db.session import Reads, connection_of
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.services.catalog.id_stream import IdStream
from trajcache.services.catalog.states_cache import StatesCache

if TYPE_CHECKING:
    from typing import TypeAlias

    AnySelect: TypeAlias = sa.Select[*tuple[Any, ...]]  # a select of any columns

_STARTUP_WINDOW = 10_000  # ids below the first high-water mark that may still be in flight
_ROW, _TOMBSTONE, _RIDER, _OLDEST, _OLDEST_TOMB = 0, 1, 2, 3, 4
_SYNC_COLUMNS = 6  # kind, id, model_id, start, goal, ref: a rider's columns follow them

# The key states of given trajectories (a hit's candidates): built once, so that SQLAlchemy
# keeps its compiled form and cache key.
_STATES = sa.select(Trajectory.id, Trajectory.states, Trajectory.n_states, Trajectory.dof).where(
    Trajectory.id.in_(sa.bindparam("ids", expanding=True))
)


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
        self.reloads = 0  # times the commit log was found pruned past this replica's mark
        self._indexes: dict[str, TrajectoryIndex] = {}
        self._commits = IdStream()
        self._tombs = IdStream()
        self._started = False
        self._synced_from = -float("inf")  # when the last completed sync began (monotonic)
        self._lock = threading.Lock()
        self._states = StatesCache(states_cache_bytes)

    def clear_states(self) -> None:
        """Forget the cached key states (indexes stay: they are synchronised, not cached)."""
        self._states.clear()

    def index(
        self, reads: Reads, model: RobotModel, *, arrived: float | None = None
    ) -> TrajectoryIndex:
        """The model's index, after picking up what other replicas wrote before the request
        arrived (`time.monotonic()`; default now)."""
        asked = time.monotonic() if arrived is None else arrived
        with self._lock:
            if self._sync_due(asked):
                self._sync(reads)
            index = self._indexes.get(model.model_id)
            if index is None:
                index = self._load_model(reads, model)
            return index

    def read_with_sync(
        self, reads: Reads, rider: AnySelect, params: Mapping[str, Any], *, arrived: float
    ) -> tuple[Any, ...] | None:
        """The row of `rider` (a query of at most one row), read together with the sync that a
        request which arrived at `arrived` (`time.monotonic()`) needs: one query instead of two.

        `rider` is one more UNION ALL branch of the sync query (no ORDER BY or LIMIT of its own),
        so it reads the same snapshot. `index(..., arrived=arrived)` then needs no sync of its own.
        """
        with self._lock:
            if self._sync_due(arrived):
                return self._sync(reads, rider, params)
        row = connection_of(reads).execute(rider, params).one_or_none()
        return None if row is None else tuple(row)

    def add_stored(
        self, model_id: str, trajectory_id: int, commit_id: int | None, states: FloatArray
    ) -> None:
        """Index a trajectory this replica just stored and committed, under its commit-log id
        (module docstring), and cache its key states (as `states` reads them back: float64,
        the stored bits), so its first hit reads neither."""
        kept = np.array(states, dtype=np.float64)
        kept.flags.writeable = False
        self._states.put(int(trajectory_id), kept)
        if commit_id is None:
            return
        with self._lock:
            stream, index = self._commits, self._indexes.get(model_id)
            read = commit_id <= stream.hwm and commit_id not in stream.gaps
            if not self._started or index is None or read:
                return  # a sync reads it, or read it; an index loaded later holds it
            _add_rows(index, [(int(trajectory_id), kept[0], kept[-1])])
            stream.advance([commit_id], time.monotonic())

    def states(self, reads: Reads, ids: Iterable[int]) -> dict[int, FloatArray]:
        """Key states (read-only arrays) of the trajectories `ids` that exist, by id."""
        found, missing = self._states.get_many(ids)
        if missing:  # one prepared Core statement: the ORM's layer cost more than the read
            rows = connection_of(reads).execute(_STATES, {"ids": missing}).all()
            for row in rows:
                states = unpack_states(row.states, n_states=row.n_states, dof=row.dof)
                states.flags.writeable = False
                found[int(row.id)] = self._states.put(int(row.id), states)
        return found

    def sizes(self) -> dict[str, int]:
        """Number of indexed trajectories per loaded model."""
        with self._lock:
            return {m: len(i) for m, i in self._indexes.items()}

    def _start(self, reads: Reads, now: float) -> None:
        for stream, column in (
            (self._commits, TrajectoryCommit.id),
            (self._tombs, TrajectoryTombstone.id),
        ):
            top = connection_of(reads).execute(sa.select(sa.func.max(column))).scalar() or 0
            floor = max(0, top - _STARTUP_WINDOW)
            seen = (
                connection_of(reads)
                .execute(sa.select(column).where(column > floor))
                .scalars()
                .all()
            )
            stream.hwm = floor
            stream.advance([int(i) for i in seen], now)
            stream.hwm = max(stream.hwm, int(top))
        self._started = True

    def _sync_due(self, asked: float) -> bool:
        """Whether a request that arrived at `asked` needs a sync (call holding the lock)."""
        return not self._started or self._synced_from < asked - self.sync_interval_s

    def _sync(
        self,
        reads: Reads,
        rider: AnySelect | None = None,
        rider_params: Mapping[str, Any] | None = None,
    ) -> tuple[Any, ...] | None:
        began = time.monotonic()
        if not self._started:
            self._start(reads, began)
        found = self._read_changes(reads, began, rider, rider_params or {})
        self.syncs += 1
        self._synced_from = began
        return found

    def _read_changes(
        self,
        reads: Reads,
        now: float,
        rider: AnySelect | None,
        rider_params: Mapping[str, Any],
    ) -> tuple[Any, ...] | None:
        """New and missing commit-log rows with their trajectories, tombstones, the oldest log
        id (and `rider`'s row) in one query; rows are applied before tombstones. Returns the
        row of `rider`, if any."""
        commit_gaps = self._commits.wanted_gaps(now, self.gap_ttl_s)
        tomb_gaps = self._tombs.wanted_gaps(now, self.gap_ttl_s)
        params: dict[str, Any] = {"commit_hwm": self._commits.hwm, "tomb_hwm": self._tombs.hwm}
        if commit_gaps:
            params["commit_gaps"] = commit_gaps
        if tomb_gaps:
            params["tomb_gaps"] = tomb_gaps
        statement = _changes_statement(bool(commit_gaps), bool(tomb_gaps), rider)
        if rider is not None:
            params.update(rider_params)
        changes = connection_of(reads).execute(statement, params).all()
        ridden = next((tuple(c)[_SYNC_COLUMNS:] for c in changes if c.kind == _RIDER), None)
        oldest = next((c.id for c in changes if c.kind == _OLDEST), None)
        oldest_tomb = next((c.id for c in changes if c.kind == _OLDEST_TOMB), None)
        if (oldest is not None and oldest > self._commits.hwm + 1) or (
            oldest_tomb is not None and oldest_tomb > self._tombs.hwm + 1
        ):
            self._reload(reads, now)  # rows above a mark were pruned unread
            return ridden
        logged = [c for c in changes if c.kind == _ROW]
        tombstones = [c for c in changes if c.kind == _TOMBSTONE]
        self._apply(logged, tombstones)
        self._commits.advance([int(c.id) for c in logged], now)
        self._tombs.advance([int(t.id) for t in tombstones], now)
        return ridden

    def _apply(self, logged: Sequence[Any], tombstones: Sequence[Any]) -> None:
        """Add the logged trajectories of loaded models, then drop the tombstoned ones."""
        by_model: dict[str, list[tuple[int, Any, Any]]] = {}
        for row in logged:
            if row.ref is not None and row.model_id in self._indexes:
                by_model.setdefault(row.model_id, []).append((row.ref, row.start, row.goal))
        for model_id, model_rows in by_model.items():
            _add_rows(self._indexes[model_id], model_rows)
        for tomb in tombstones:
            self._states.discard(int(tomb.ref))
            index = self._indexes.get(tomb.model_id)
            if index is not None and tomb.ref in index:
                index.remove(np.array([tomb.ref], dtype=np.int64))

    def _reload(self, reads: Reads, now: float) -> None:
        """Start over as a new replica: indexes load again when next asked for."""
        self.reloads += 1
        self._indexes.clear()
        self._states.clear()
        self._commits, self._tombs = IdStream(), IdStream()
        self._start(reads, now)

    def _load_model(self, reads: Reads, model: RobotModel) -> TrajectoryIndex:
        rows = (
            connection_of(reads)
            .execute(
                sa.select(Trajectory.id, Trajectory.start, Trajectory.goal).where(
                    Trajectory.model_id == model.model_id
                )
            )
            .all()
        )
        index = TrajectoryIndex(model.dof, base=model.base)
        _add_rows(index, [(r.id, r.start, r.goal) for r in rows])
        self._indexes[model.model_id] = index
        return index


@functools.cache
def _changes_statement(
    commit_gaps: bool, tomb_gaps: bool, rider: AnySelect | None = None
) -> sa.CompoundSelect[Any]:
    """Commit-log rows above their high-water mark (`:commit_hwm`) or, when asked, among the
    gaps (`:commit_gaps`), each with the trajectories in its id range (one row with none when
    they are gone); tombstones likewise (`:tomb_hwm`, `:tomb_gaps`); the oldest log id and the
    oldest tombstone id; and
    the row of `rider` if given (its columns after the sync's, null in the other branches).
    Built once per shape and rider."""
    extra = list(rider.selected_columns) if rider is not None else []
    blanks = [sa.cast(sa.null(), c.type).label(f"rider_{i}") for i, c in enumerate(extra)]
    logged = (
        sa.select(
            _kind(_ROW).label("kind"),
            TrajectoryCommit.id.label("id"),
            Trajectory.model_id.label("model_id"),
            Trajectory.start.label("start"),
            Trajectory.goal.label("goal"),
            Trajectory.id.label("ref"),
            *blanks,
        )
        .select_from(TrajectoryCommit)
        .outerjoin(
            Trajectory, Trajectory.id.between(TrajectoryCommit.first_id, TrajectoryCommit.last_id)
        )
        .where(_above_or_in(TrajectoryCommit.id, "commit", commit_gaps))
    )
    tombs = sa.select(
        _kind(_TOMBSTONE),
        TrajectoryTombstone.id,
        TrajectoryTombstone.model_id,
        *_nulls(Trajectory.start, Trajectory.goal),
        TrajectoryTombstone.trajectory_id,
        *blanks,
    ).where(_above_or_in(TrajectoryTombstone.id, "tomb", tomb_gaps))
    oldest = sa.select(
        _kind(_OLDEST),
        sa.func.min(TrajectoryCommit.id),
        *_nulls(Trajectory.model_id, Trajectory.start, Trajectory.goal, Trajectory.id),
        *blanks,
    )
    oldest_tomb = sa.select(
        _kind(_OLDEST_TOMB),
        sa.func.min(TrajectoryTombstone.id),
        *_nulls(Trajectory.model_id, Trajectory.start, Trajectory.goal, Trajectory.id),
        *blanks,
    )
    if rider is None:
        return sa.union_all(logged, tombs, oldest, oldest_tomb)
    ridden = rider.with_only_columns(
        _kind(_RIDER),
        *_nulls(Trajectory.id, Trajectory.model_id, Trajectory.start, Trajectory.goal),
        sa.cast(sa.null(), sa.BigInteger),
        *extra,
        maintain_column_froms=True,
    )
    return sa.union_all(logged, tombs, oldest, oldest_tomb, ridden)


def _kind(kind: int) -> sa.ColumnElement[int]:
    return sa.literal_column(str(kind), sa.Integer)


def _nulls(*columns: InstrumentedAttribute[Any]) -> list[sa.ColumnElement[Any]]:
    """Nulls of the types of `columns`, for the branches that have no such value."""
    return [sa.cast(sa.null(), c.type) for c in columns]


def _above_or_in(
    column: InstrumentedAttribute[int], name: str, gaps: bool
) -> sa.ColumnElement[bool]:
    above = column > sa.bindparam(f"{name}_hwm", type_=sa.BigInteger)
    if not gaps:
        return above
    return sa.or_(above, column.in_(sa.bindparam(f"{name}_gaps", expanding=True)))


def _add_rows(index: TrajectoryIndex, rows: Sequence[tuple[int, Any, Any]]) -> None:
    """Add the (id, start, goal) rows not indexed yet (adding is idempotent)."""
    fresh = [r for r in rows if r[0] not in index]
    if not fresh:
        return
    ids = np.array([r[0] for r in fresh], dtype=np.int64)
    index.add(ids, np.array([r[1] for r in fresh], float), np.array([r[2] for r in fresh], float))
