"""Plan bookkeeping written off the request path: usage counters and plan events, in order.

An answered plan does not wait for its bookkeeping. Its outcome (`outcomes.record_outcome`), or
a refusal (`refusals`), submits a :class:`PlanRecord` (the trajectory that served, the
candidates that failed validation, the plan event, and for a newly planned trajectory its
quality metrics and timing, a :class:`QualityJob` the writer computes just before the record's
transaction) and gets a sequence number; one writer thread per process commits records in
submission order, many per transaction: counter updates grouped per trajectory (in id order, so
replicas writing the same rows cannot deadlock), the events as one multi-row insert, and the
quality columns of new trajectories (`record_batch`). Records are stamped by the recorder's
clock (`now`, injectable) when the plan is answered, not when they are written. Every answer of
the plan flow — hit, miss, failure, planned — is recorded here, and nothing else writes those
counters or plan events.

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
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime

from sqlalchemy import Engine
from sqlalchemy.exc import DataError, IntegrityError, SQLAlchemyError

from trajcache.db.models import utcnow
from trajcache.services.bookkeeping.record_batch import PlanRecord, QualityJob
from trajcache.services.bookkeeping.record_batch import committed as _committed
from trajcache.services.bookkeeping.record_batch import write_records as _write

__all__ = ["PlanRecord", "PlanRecorder", "QualityJob", "RecorderStats"]

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RecorderStats:
    """Counters of a recorder."""

    submitted: int
    written: int
    pending: int
    dropped: int


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
        clock: Callable[[], datetime] = utcnow,
    ) -> None:
        self._engine = engine
        self.clock = clock  # stamps records: when a plan was answered
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

    def now(self) -> datetime:
        """The time a record submitted now is stamped with (the recorder's clock)."""
        return self.clock()

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
