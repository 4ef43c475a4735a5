"""Plan bookkeeping written off the request path: usage counters and plan events, in order.

An answered plan does not wait for its bookkeeping. The plan flow submits a :class:`PlanRecord`
(the trajectory that served, the candidates that failed validation, the plan event, and for a
newly planned trajectory its quality metrics and timing, a :class:`QualityJob` the writer
computes just before the record's transaction) and gets a sequence number; one writer thread
per process commits records in submission order, many per transaction: counter updates grouped
per trajectory (in id order, so replicas writing the same rows cannot deadlock), the events as
one multi-row insert, and the quality columns of new trajectories. Event timestamps are taken when
the plan is answered, not when it is written.

The writer lingers up to `linger_s` after the first record of a batch, so that an answer goes
out before the write competes with it for the interpreter, and more records share a transaction.
It stops lingering as soon as someone waits for a record (`wait`, `flush`, or `written`, which
the HTTP layer awaits once the answer is sent), at shutdown, or when the batch is full.

Reliability:
- a transaction that fails is rolled back and retried with backoff; its records stay at the head
  of the queue, so nothing is reordered or skipped while the database is busy or away;
- a retry is never counted twice: each record's event carries a unique key (`record_key`), and
  before writing a batch again the writer looks for its first key, since a COMMIT can reach the
  database while its answer is lost (the connection dropped);
- a batch the database rejects for its data is retried record by record, and only a record that
  fails on its own is dropped (logged and counted);
- :meth:`PlanRecorder.close` (service shutdown) writes everything still queued before it returns,
  waiting up to its timeout for an unavailable database;
- :meth:`PlanRecorder.written` lets the HTTP layer keep a request's cycle open, after its response
  is sent, until its record is committed; a server's graceful shutdown waits for those cycles.

A record submitted after `close` is written synchronously by the caller.
"""

from __future__ import annotations

import asyncio
import contextlib
import heapq
import itertools
import logging
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy import Engine
from sqlalchemy.exc import DataError, IntegrityError, SQLAlchemyError

from trajcache.db.models import PlanEvent, Trajectory

__all__ = ["PlanRecord", "PlanRecorder", "QualityJob", "RecorderStats"]

_log = logging.getLogger(__name__)
_T = Trajectory

_AT = _T.last_used_at.type
# The counters of one trajectory for a batch, served or not. Every row of a batch is updated by
# this one statement in id order, so writers (of all replicas) lock rows in the same order and
# cannot deadlock. A served row's failure streak is what followed its last hit in the batch; the
# streak of a row that only failed validation grows.
_USAGE = (
    sa.update(_T)
    .where(_T.id == sa.bindparam("b_id"))
    .values(
        hits=_T.hits + sa.bindparam("b_hits"),
        failures=_T.failures + sa.bindparam("b_failures"),
        consecutive_failures=sa.case(
            (sa.bindparam("b_served", type_=sa.Boolean), sa.bindparam("b_streak")),
            else_=_T.consecutive_failures + sa.bindparam("b_failures"),
        ),
        last_used_at=sa.func.coalesce(sa.bindparam("b_at", type_=_AT), _T.last_used_at),
        last_validated_at=sa.func.coalesce(sa.bindparam("b_at", type_=_AT), _T.last_validated_at),
        real_validations=_T.real_validations + sa.bindparam("b_real"),
        last_real_validated_at=sa.func.coalesce(
            sa.bindparam("b_real_at", type_=_AT), _T.last_real_validated_at
        ),
    )
)

_EVENTS = sa.insert(PlanEvent)
_QUALITY = (
    sa.update(_T)
    .where(_T.id == sa.bindparam("q_id"))
    .values(
        length=sa.bindparam("length"),
        ee_length=sa.bindparam("ee_length"),
        min_clearance=sa.bindparam("min_clearance"),
        duration_s=sa.bindparam("duration_s"),
        quality=sa.bindparam("quality", type_=_T.quality.type),
    )
)


class QualityJob:
    """The quality columns of a trajectory the planner just stored, computed off the request
    path (by the writer, before the record's transaction; once, whatever the retries)."""

    def __init__(self, trajectory_id: int, compute: Callable[[], Mapping[str, Any] | None]):
        self.trajectory_id = trajectory_id
        self._compute: Callable[[], Mapping[str, Any] | None] | None = compute
        self._values: Mapping[str, Any] | None = None

    def values(self) -> Mapping[str, Any] | None:
        """The column values (None: nothing could be computed); computed on the first call."""
        if self._compute is not None:
            compute, self._compute = self._compute, None
            try:
                self._values = compute()
            except Exception:  # a metric must never cost the record
                _log.warning("quality of trajectory %d could not be computed", self.trajectory_id,
                             exc_info=True)  # fmt: skip
        return self._values


@dataclass(frozen=True)
class PlanRecord:
    """The bookkeeping of one plan request."""

    at: datetime  # when the plan was answered
    served: int | None  # the cached trajectory that was returned
    failed: tuple[int, ...]  # cached candidates that failed validation
    event: Mapping[str, Any]  # plan_events column values (without id and created_at)
    real: bool = False  # served to a real robot: counts as a real-world validation
    key: str = field(default_factory=lambda: uuid.uuid4().hex)  # its event's record_key
    quality: QualityJob | None = None  # a newly planned trajectory's quality, written with it


@dataclass(frozen=True)
class RecorderStats:
    """Counters of a recorder."""

    submitted: int
    written: int
    pending: int
    dropped: int


@dataclass
class _Usage:
    hits: int = 0
    failures: int = 0
    streak: int = 0  # failures since the last hit in the batch
    served_at: datetime | None = None
    real: int = 0  # hits by real robots
    real_at: datetime | None = None


@dataclass
class _State:
    queue: deque[tuple[int, PlanRecord]] = field(default_factory=deque)
    submitted: int = 0
    written: int = 0  # every record up to this sequence number is committed (or dropped)
    urgent: int = 0  # someone waits for the records up to this one: write without lingering
    dropped: int = 0
    waiters: list[tuple[int, int, Callable[[], None]]] = field(default_factory=list)


class PlanRecorder:
    """Writes plan records in submission order on a background thread."""

    def __init__(
        self,
        engine: Engine,
        *,
        max_batch: int = 500,
        max_pending: int = 50_000,
        retry_max_s: float = 2.0,
        linger_s: float = 0.01,
    ) -> None:
        self._engine = engine
        self.linger_s = linger_s
        self.max_batch = max_batch
        self.max_pending = max_pending
        self.retry_max_s = retry_max_s
        self._state = _State()
        self._cond = threading.Condition()
        self._tiebreak = itertools.count()
        self._thread: threading.Thread | None = None
        self._closing = False
        self._closed = False
        self._deadline = float("inf")
        self._inflight = 0  # the last sequence number of the batch being written

    def submit(self, record: PlanRecord) -> int:
        """Queue `record`; return its sequence number (see `wait` and `written`)."""
        with self._cond:
            state = self._state
            state.submitted += 1
            seq = state.submitted
            if not self._closed:
                state.queue.append((seq, record))
                self._trim()
                self._start()
                if len(state.queue) == 1 or len(state.queue) >= self.max_batch:
                    self._cond.notify_all()  # a batch starts, or is full
                return seq
        self._mark_written(seq, self._write_with_retry([(seq, record)]))  # after close
        return seq

    def wait(self, seq: int, timeout: float | None = None) -> bool:
        """Block until record `seq` is settled (committed, or dropped and logged); False on
        timeout."""
        with self._cond:
            self._hurry(seq)
            return self._cond.wait_for(lambda: self._state.written >= seq, timeout)

    def flush(self, timeout: float | None = None) -> bool:
        """Block until everything submitted so far is settled; False on timeout."""
        with self._cond:
            seq = self._state.submitted
        return self.wait(seq, timeout)

    async def written(self, seq: int, timeout: float = 10.0) -> bool:
        """Wait (without a thread) until record `seq` is settled; False on timeout."""
        loop = asyncio.get_running_loop()
        done: asyncio.Future[None] = loop.create_future()

        def resolve() -> None:
            if not done.done():
                done.set_result(None)

        def fire() -> None:
            loop.call_soon_threadsafe(resolve)

        with self._cond:
            if self._state.written >= seq:
                return True
            heapq.heappush(self._state.waiters, (seq, next(self._tiebreak), fire))
            self._hurry(seq)
        try:
            await asyncio.wait_for(done, timeout)
        except TimeoutError:
            return False
        return True

    def stats(self) -> RecorderStats:
        """How many records were submitted, written, are pending and were dropped."""
        with self._cond:
            s = self._state
            return RecorderStats(s.submitted, s.written, len(s.queue), s.dropped)

    def close(self, timeout: float = 10.0) -> None:
        """Write what is queued (waiting at most `timeout` for the database) and stop."""
        with self._cond:
            if self._closed:
                return
            self._closing = True
            self._deadline = time.monotonic() + timeout
            thread = self._thread
            self._cond.notify_all()
        if thread is not None:
            thread.join()
        with self._cond:
            self._closed = True
            leftover = list(self._state.queue)  # submitted after the writer's last look
            self._state.queue.clear()
        if leftover:
            self._mark_written(leftover[-1][0], self._write_with_retry(leftover))

    def _hurry(self, seq: int) -> None:
        """Have the writer write up to `seq` without lingering (call holding the lock)."""
        if seq > self._state.urgent:
            self._state.urgent = seq
            self._cond.notify_all()

    def _start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="plan-records", daemon=True)
            self._thread.start()

    def _trim(self) -> None:
        """Drop the oldest records beyond `max_pending` (the database has been away too long),
        except those the writer is trying to write."""
        state = self._state
        excess = len(state.queue) - self.max_pending
        if excess <= 0:
            return
        kept = [item for item in state.queue if item[0] <= self._inflight]
        rest = list(state.queue)[len(kept) :]
        excess = min(excess, len(rest))
        state.queue = deque(kept + rest[excess:])
        state.dropped += excess
        _log.error("plan records: %d dropped, %d still pending", excess, len(state.queue))

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: bool(self._state.queue) or self._closing)
                if not self._state.queue:
                    return
                self._linger()
                batch = list(itertools.islice(self._state.queue, self.max_batch))
                self._inflight = batch[-1][0]
            try:
                lost = self._write_with_retry(batch)
            except Exception:  # a bug must not stop the writer; the batch is lost, logged
                _log.exception("plan records: %d lost", len(batch))
                lost = len(batch)
            with self._cond:
                queue = self._state.queue
                last = batch[-1][0]
                while queue and queue[0][0] <= last:
                    queue.popleft()
            self._mark_written(last, lost)

    def _linger(self) -> None:
        """Wait (holding the lock) until `linger_s` has passed, or the batch must go now."""
        state = self._state
        deadline = time.monotonic() + self.linger_s
        while (
            not self._closing
            and state.urgent <= state.written
            and len(state.queue) < self.max_batch
        ):
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return
            self._cond.wait(remaining)

    def _mark_written(self, seq: int, lost: int) -> None:
        fired: list[Callable[[], None]] = []
        with self._cond:
            state = self._state
            state.written = max(state.written, seq)
            state.dropped += lost
            while state.waiters and state.waiters[0][0] <= state.written:
                fired.append(heapq.heappop(state.waiters)[2])
            self._cond.notify_all()
        for fire in fired:
            with contextlib.suppress(RuntimeError):  # the waiting event loop is gone
                fire()

    def _write_with_retry(self, batch: list[tuple[int, PlanRecord]]) -> int:
        """Write `batch`, retrying while the database is unavailable; return records dropped."""
        delay = 0.01
        failing = False
        while True:
            try:
                if failing and _committed(self._engine, batch[0][1]):
                    _log.info("plan records: the failed write had been committed")
                    return 0
                _write(self._engine, (record for _, record in batch))
            except (DataError, IntegrityError) as exc:
                if len(batch) == 1:
                    _log.error("plan record rejected by the database, dropped: %s", exc)
                    return 1
                return sum(self._write_with_retry([item]) for item in batch)
            except SQLAlchemyError as exc:
                if time.monotonic() >= self._deadline:
                    _log.error("plan records: database still unavailable, %d lost", len(batch))
                    return len(batch)
                if not failing:
                    _log.warning("plan records: write failed, retrying: %s", exc)
                    failing = True
                time.sleep(min(delay, max(0.0, self._deadline - time.monotonic())))
                delay = min(delay * 2, self.retry_max_s)
            else:
                if failing:
                    _log.info("plan records: writing again")
                return 0


def _write(engine: Engine, records: Iterable[PlanRecord]) -> None:
    """Commit the records' counter updates, events and quality columns in one transaction."""
    usage: dict[int, _Usage] = {}
    events: list[dict[str, Any]] = []
    qualities: list[dict[str, Any]] = []
    for record in records:
        values = record.quality.values() if record.quality is not None else None
        if values is not None and record.quality is not None:
            qualities.append({"q_id": record.quality.trajectory_id, **values})
        for trajectory_id in record.failed:
            u = usage.setdefault(trajectory_id, _Usage())
            u.failures += 1
            u.streak += 1
        if record.served is not None:
            u = usage.setdefault(record.served, _Usage())
            u.hits += 1
            u.streak = 0
            u.served_at = record.at
            if record.real:
                u.real += 1
                u.real_at = record.at
        events.append({**record.event, "created_at": record.at, "record_key": record.key})
    rows = [
        {"b_id": i, "b_hits": u.hits, "b_failures": u.failures, "b_served": u.served_at is not None,
         "b_streak": u.streak, "b_at": u.served_at, "b_real": u.real, "b_real_at": u.real_at}
        for i, u in sorted(usage.items())
    ]  # fmt: skip
    with engine.begin() as conn:
        if rows:
            conn.execute(_USAGE, _one_or_many(rows))
        if events:
            conn.execute(_EVENTS, _one_or_many(events))
        for values in qualities:  # few: one per planned trajectory
            conn.execute(_QUALITY, values)


def _committed(engine: Engine, record: PlanRecord) -> bool:
    """Whether `record` is in the database: its batch's transaction was committed (a batch is
    written whole or not at all)."""
    with engine.connect() as conn:
        found = conn.execute(_KEY_FOUND, {"key": record.key}).first()
    return found is not None


_KEY_FOUND = sa.select(PlanEvent.id).where(PlanEvent.record_key == sa.bindparam("key"))


def _one_or_many(params: list[dict[str, Any]]) -> dict[str, Any] | list[dict[str, Any]]:
    """A lone parameter set is executed as such: an executemany of one costs the driver more
    (psycopg runs it as a pipeline with its own sync)."""
    return params[0] if len(params) == 1 else params
