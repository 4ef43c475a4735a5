"""Plan events and their hourly rollups as columns, read in one query each.

`EventRows` holds either kind the same way (an event is a rollup of one), so statistics and
rollups are computed by one code path: counts and sums per row, and histogram entries.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np
import numpy.typing as npt
import sqlalchemy as sa
from sqlalchemy.orm import InstrumentedAttribute, Session

from trajcache.db.models import PlanEvent, PlanEventRollup
from trajcache.services.stats import histograms

ObjArray = npt.NDArray[np.object_]


@dataclass
class EventRows:
    """Plan events or rollups as columns: one row per event (`n` = 1) or per rollup (`n` ≥ 1)."""

    t: npt.NDArray[np.int64]  # epoch seconds of the event, or of the rollup's hour
    robot: ObjArray
    requester: ObjArray  # who `robot` is: "robot" or "seed_job"
    model: ObjArray
    source: ObjArray  # None when no trajectory was returned
    status: ObjArray
    goal_kind: ObjArray  # "joint", "pose"; None: recorded before the kind was
    n: npt.NDArray[np.int64]
    sums: npt.NDArray[np.float64]  # (rows, len(METRICS)) timing sums in ms
    # Histogram entries: (row, metric, bin, count).
    entries: tuple[
        npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64]
    ]

    def __len__(self) -> int:
        return int(self.t.size)

    @staticmethod
    def concat(parts: list[EventRows]) -> EventRows:
        """All rows of `parts`, in order."""
        offsets = np.cumsum([0] + [len(p) for p in parts])
        return EventRows(
            t=np.concatenate([p.t for p in parts]),
            robot=np.concatenate([p.robot for p in parts]),
            requester=np.concatenate([p.requester for p in parts]),
            model=np.concatenate([p.model for p in parts]),
            source=np.concatenate([p.source for p in parts]),
            status=np.concatenate([p.status for p in parts]),
            goal_kind=np.concatenate([p.goal_kind for p in parts]),
            n=np.concatenate([p.n for p in parts]),
            sums=np.concatenate([p.sums for p in parts]).reshape(-1, len(histograms.METRICS)),
            entries=(
                np.concatenate(
                    [p.entries[0] + o for p, o in zip(parts, offsets[:-1], strict=True)]
                ),
                np.concatenate([p.entries[1] for p in parts]),
                np.concatenate([p.entries[2] for p in parts]),
                np.concatenate([p.entries[3] for p in parts]),
            ),
        )


def epoch_seconds(
    session: Session, column: InstrumentedAttribute[datetime]
) -> sa.ColumnElement[int]:
    """SQL for a timestamp column as whole seconds since the epoch (UTC)."""
    if session.get_bind().dialect.name == "sqlite":
        return sa.cast(sa.func.strftime("%s", column), sa.BigInteger)
    return sa.cast(sa.func.floor(sa.extract("epoch", column)), sa.BigInteger)


@dataclass(frozen=True)
class EventFilter:
    """Which plan events count: one robot's, one model's, one requester's (None: any)."""

    robot_id: str | None = None
    model_id: str | None = None
    requester: str | None = None  # "robot" or "seed_job"

    def conditions(
        self, table: type[PlanEvent] | type[PlanEventRollup]
    ) -> list[sa.ColumnElement[bool]]:
        """SQL conditions on `table`'s rows (events or rollups) for the values given."""
        wanted = (
            (table.robot_id, self.robot_id),
            (table.model_id, self.model_id),
            (table.requester, self.requester),
        )
        return [column == value for column, value in wanted if value is not None]


ANY = EventFilter()


def _keys(cols: list[Any]) -> dict[str, Any]:
    """The first six columns of a query below: time, robot, requester, model, source, status."""
    names = ("robot", "requester", "model", "source", "status")
    keys = {name: np.array(cols[k], dtype=object) for k, name in enumerate(names, start=1)}
    return {"t": np.array(cols[0], dtype=np.int64), **keys}


def fetch_events(
    session: Session,
    begin: datetime,
    end: datetime,
    filters: EventFilter = ANY,
) -> EventRows:
    """Plan events with `begin` ≤ created_at < `end`, as columns."""
    e = PlanEvent
    query = sa.select(
        epoch_seconds(session, e.created_at),
        e.robot_id,
        e.requester,
        e.model_id,
        e.source,
        e.status,
        e.lookup_ms,
        e.validate_ms,
        e.plan_ms,
        e.total_ms,
        e.goal_kind,
    ).where(e.created_at >= begin, e.created_at < end, *filters.conditions(e))
    rows = session.connection().execute(query).all()  # core rows: no ORM overhead
    count = len(rows)
    cols = list(zip(*rows, strict=True)) if rows else [()] * 11
    sums = np.array(cols[6:10], dtype=np.float64).T.reshape(count, len(histograms.METRICS))
    metrics = len(histograms.METRICS)
    return EventRows(
        **_keys(cols),
        goal_kind=np.array(cols[10], dtype=object),
        n=np.ones(count, dtype=np.int64),
        sums=sums,
        entries=(
            np.repeat(np.arange(count, dtype=np.int64), metrics),
            np.tile(np.arange(metrics, dtype=np.int64), count),
            histograms.bin_of(sums.ravel()),
            np.ones(count * metrics, dtype=np.int64),
        ),
    )


def first_event_at(
    session: Session,
    begin: datetime,
    end: datetime,
    filters: EventFilter = ANY,
) -> datetime | None:
    """When the first plan event with `begin` ≤ created_at < `end` was written (one index
    seek), or None."""
    e = PlanEvent
    query = sa.select(e.created_at).where(
        e.created_at >= begin, e.created_at < end, *filters.conditions(e)
    )
    first: datetime | None = session.scalar(query.order_by(e.created_at).limit(1))
    return first


def fetch_rollups(
    session: Session,
    begin: datetime,
    end: datetime,
    filters: EventFilter = ANY,
) -> EventRows:
    """Rollups of the hours `begin` ≤ hour < `end`, as columns."""
    r = PlanEventRollup
    query = sa.select(
        epoch_seconds(session, r.bucket_start),
        r.robot_id,
        r.requester,
        r.model_id,
        r.source,
        r.status,
        r.requests,
        r.lookup_ms,
        r.validate_ms,
        r.plan_ms,
        r.total_ms,
        r.histograms,
        r.goal_kind,
    ).where(r.bucket_start >= begin, r.bucket_start < end, *filters.conditions(r))
    rows = session.connection().execute(query).all()  # core rows: no ORM overhead
    count = len(rows)
    cols = list(zip(*rows, strict=True)) if rows else [()] * 13
    return EventRows(
        **_keys(cols),
        goal_kind=np.array(cols[12], dtype=object),
        n=np.array(cols[6], dtype=np.int64),
        sums=np.array(cols[7:11], dtype=np.float64).T.reshape(count, len(histograms.METRICS)),
        entries=histograms.decode(list(cols[11])),
    )


def codes(values: ObjArray) -> tuple[ObjArray, npt.NDArray[np.int64]]:
    """The distinct values (None sorts as "") and each row's index into them."""
    keys = np.where(values == None, "", values).astype(str)  # noqa: E711  (elementwise)
    unique, inverse = np.unique(keys, return_inverse=True)
    labels = np.array([u or None for u in unique.tolist()], dtype=object)
    return labels, inverse.reshape(-1).astype(np.int64)
