"""One transaction of plan records: the counter updates, events, quality columns and
certificates they write.

The only statements that write trajectories' usage counters (hits, failures, failure streaks,
real-robot validations) and plan events; `records` runs them in submission order.
"""

from __future__ import annotations

import logging
import uuid
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy import Engine

from trajcache.db.models import PlanEvent, Trajectory
from trajcache.services.catalog.certificates import CertificateWrite, write_certificates

__all__ = ["EventDetails", "PlanRecord", "QualityJob", "WriterJob", "committed", "write_records"]

_log = logging.getLogger(__name__)


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


class WriterJob:
    """Work that a request leaves to the writer (off the request path, before the record's
    transaction; once, whatever the retries), whose result the record does not hold: measuring
    clearances for later hits. A failure is logged; the record is written."""

    def __init__(self, what: str, run: Callable[[], None]):
        self.what = what
        self._run: Callable[[], None] | None = run

    def run(self) -> None:
        """Do it, the first time only."""
        if self._run is not None:
            run, self._run = self._run, None
            try:
                run()
            except Exception:  # it must never cost the record
                _log.warning("%s could not be done", self.what, exc_info=True)


class EventDetails:
    """Plan event columns computed off the request path (by the writer, before the record's
    transaction; once, whatever the retries): why the candidates were rejected."""

    def __init__(self, compute: Callable[[], Mapping[str, Any]]):
        self._compute: Callable[[], Mapping[str, Any]] | None = compute
        self._values: Mapping[str, Any] = {}

    def values(self) -> Mapping[str, Any]:
        """The column values ({} when they could not be computed); computed on the first call."""
        if self._compute is not None:
            compute, self._compute = self._compute, None
            try:
                self._values = compute()
            except Exception:  # a detail must never cost the record
                _log.warning("plan event details could not be computed", exc_info=True)
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
    details: EventDetails | None = None  # event columns the writer computes
    certificates: tuple[CertificateWrite, ...] = ()  # what its validations proved
    jobs: tuple[WriterJob, ...] = ()  # done first, for later requests


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


@dataclass
class _Usage:
    hits: int = 0
    failures: int = 0
    streak: int = 0  # failures since the last hit in the batch
    served_at: datetime | None = None
    real: int = 0  # hits by real robots
    real_at: datetime | None = None


def write_records(engine: Engine, records: Iterable[PlanRecord]) -> None:
    """Commit the records' counter updates, events, quality columns and certificates in one
    transaction."""
    records = list(records)
    usage: dict[int, _Usage] = {}
    events: list[dict[str, Any]] = []
    qualities: list[dict[str, Any]] = []
    for record in records:
        for job in record.jobs:
            job.run()
        for write in record.certificates:  # measured before the transaction, as quality is
            if write.clearances is not None:
                write.clearances.run()
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
        details = record.details.values() if record.details is not None else {}
        events.append(
            {**record.event, **details, "created_at": record.at, "record_key": record.key}
        )
    rows = [
        {"b_id": i, "b_hits": u.hits, "b_failures": u.failures, "b_served": u.served_at is not None,
         "b_streak": u.streak, "b_at": u.served_at, "b_real": u.real, "b_real_at": u.real_at}
        for i, u in sorted(usage.items())
    ]  # fmt: skip
    columns = set().union(*events) if events else set()
    events = [dict.fromkeys(columns) | event for event in events]  # one insert: the same keys
    with engine.begin() as conn:
        if rows:
            conn.execute(_USAGE, _one_or_many(rows))
        if events:
            conn.execute(_EVENTS, _one_or_many(events))
        for values in qualities:  # few: one per planned trajectory
            conn.execute(_QUALITY, values)
        for record in records:
            write_certificates(conn, record.certificates, record.at)


def committed(engine: Engine, record: PlanRecord) -> bool:
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
