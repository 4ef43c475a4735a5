"""Plan events, newest first: filtered pages with a keyset cursor, a trajectory's usage, and
the requests of a window by goal kind.

Pages are ordered by (created_at, id) descending and continue after the last row of the
previous page (`cursor`), so rows written meanwhile never shift or repeat a page, and a page
costs the same however deep it is. No total is counted: at millions of events a COUNT of a
filter would cost more than the page.
"""

from __future__ import annotations

import base64
import binascii
from collections import Counter
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import sqlalchemy as sa
from sqlalchemy.orm import Session, defer

from trajcache.db.models import PlanEvent, PlanEventRollup, PlanEventRollupState, Trajectory
from trajcache.services.errors import InvalidInputError
from trajcache.services.stats.event_rows import EventFilter
from trajcache.services.stats.rollups import ROLLUP_S, floor_hour

STATUSES = ("success", "miss", "failure", "error", "refused")  # refused: no answer (4xx)
SOURCES = ("cache", "planner", "none")  # none: no trajectory was returned
REQUESTERS = ("robot", "seed_job")  # who asked: a robot, or a seed job
GOAL_KINDS = ("joint", "pose", "unknown")  # unknown: recorded before the kind was
_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)


@dataclass(frozen=True)
class PlanEventPage:
    """A page of plan events and the cursor of the next one (None on the last page)."""

    items: list[PlanEvent]
    next_cursor: str | None


def encode_cursor(event: PlanEvent) -> str:
    """An opaque cursor that continues after `event`."""
    micros = (event.created_at - _EPOCH) // timedelta(microseconds=1)
    return base64.urlsafe_b64encode(f"{micros}:{event.id}".encode()).decode().rstrip("=")


def decode_cursor(cursor: str) -> tuple[datetime, int]:
    """The (created_at, id) a cursor continues after; a 422 for anything else."""
    try:
        text = base64.urlsafe_b64decode(cursor + "=" * (-len(cursor) % 4)).decode()
        micros, event_id = (int(part) for part in text.split(":"))
        if not 0 < event_id < 2**63:
            raise ValueError(event_id)
        return _EPOCH + timedelta(microseconds=micros), event_id
    except (binascii.Error, UnicodeDecodeError, ValueError, OverflowError):
        raise InvalidInputError(
            "query.cursor: not a cursor returned by this endpoint (use next_cursor)"
        ) from None


@dataclass(frozen=True)
class PlanEventFilter(EventFilter):
    """Which plan events to list: `EventFilter`'s, and by status, source, the trajectory
    returned, and time (`since` inclusive, `until` exclusive); None: any."""

    status: str | None = None
    source: str | None = None  # "none": no trajectory was returned
    trajectory_id: int | None = None
    since: datetime | None = None
    until: datetime | None = None
    goal_kind: str | None = None  # "joint", "pose", or "unknown"


def list_plan_events(
    *,
    session: Session,
    limit: int,
    cursor: str | None = None,
    filters: PlanEventFilter = PlanEventFilter(),
) -> PlanEventPage:
    """Events matching every filter given, newest first."""
    e, f = PlanEvent, filters
    status, source, requester, since, until = f.status, f.source, f.requester, f.since, f.until
    conditions = f.conditions(e)
    if since is not None and until is not None and since >= until:
        raise InvalidInputError("query.since must be before query.until")
    if status is not None and status not in STATUSES:
        raise InvalidInputError(f"query.status: {status!r} is not one of {', '.join(STATUSES)}")
    if source is not None and source not in SOURCES:
        raise InvalidInputError(f"query.source: {source!r} is not one of {', '.join(SOURCES)}")
    if requester is not None and requester not in REQUESTERS:
        raise InvalidInputError(
            f"query.requester: {requester!r} is not one of {', '.join(REQUESTERS)}"
        )
    if f.goal_kind is not None:
        conditions.append(_goal_kind_is(f.goal_kind))
    if status is not None:
        conditions.append(e.status == status)
    if source is not None:
        conditions.append(e.source.is_(None) if source == "none" else e.source == source)
    if f.trajectory_id is not None:
        conditions.append(e.trajectory_id == f.trajectory_id)
    if since is not None:
        conditions.append(e.created_at >= since)
    if until is not None:
        conditions.append(e.created_at < until)
    if cursor is not None:
        at, event_id = decode_cursor(cursor)
        conditions.append(sa.or_(e.created_at < at, sa.and_(e.created_at == at, e.id < event_id)))
    rows = list(
        session.scalars(
            sa.select(e)
            .where(*conditions)
            .order_by(e.created_at.desc(), e.id.desc())
            .limit(limit + 1)
        )
    )
    more = len(rows) > limit
    items = rows[:limit]
    return PlanEventPage(items=items, next_cursor=encode_cursor(items[-1]) if more else None)


def _goal_kind_is(kind: str) -> sa.ColumnElement[bool]:
    """The condition that an event's goal was of `kind`; InvalidInputError names a wrong one."""
    if kind not in GOAL_KINDS:
        raise InvalidInputError(f"query.goal_kind: {kind!r} is not one of {', '.join(GOAL_KINDS)}")
    column = PlanEvent.goal_kind
    return column.is_(None) if kind == "unknown" else column == kind


def goal_kind_counts(
    *, session: Session, since: datetime, until: datetime, filters: EventFilter
) -> dict[str, int]:
    """The answered requests of `[since, until)` by goal kind (refusals are not requests): the
    whole hours already rolled up from their rollups, the rest from the events."""
    rolled = session.scalar(sa.select(PlanEventRollupState.rolled_until))
    first = floor_hour(since)
    first += timedelta(seconds=ROLLUP_S) if first < since else timedelta(0)
    last = min(floor_hour(until), rolled) if rolled is not None else first
    counts: Counter[str] = Counter()
    spans = [(since, until)]
    if first < last:
        counts += _kinds(session, PlanEventRollup, first, last, filters)
        spans = [(since, first), (last, until)]
    for begin, end in spans:
        counts += _kinds(session, PlanEvent, begin, end, filters)
    return dict(counts)


def _kinds(
    session: Session,
    table: type[PlanEvent] | type[PlanEventRollup],
    begin: datetime,
    end: datetime,
    filters: EventFilter,
) -> Counter[str]:
    """The requests of `table` (events, or hourly rollups) in `[begin, end)` by goal kind."""
    count: sa.ColumnElement[int] = sa.func.count()
    at = PlanEvent.created_at
    if table is PlanEventRollup:
        count, at = sa.func.sum(PlanEventRollup.requests), PlanEventRollup.bucket_start
    kind = sa.func.coalesce(table.goal_kind, "unknown")
    rows = session.execute(
        sa.select(kind, count)
        .where(*filters.conditions(table), at >= begin, at < end, table.status != "refused")
        .group_by(kind)
    ).all()
    return Counter({str(name): int(n or 0) for name, n in rows})


def trajectory_usage(*, session: Session, trajectory_id: int, limit: int = 20) -> list[PlanEvent]:
    """The most recent plan events that returned (or stored) trajectory `trajectory_id`."""
    filters = PlanEventFilter(trajectory_id=trajectory_id)
    return list_plan_events(session=session, limit=limit, filters=filters).items


def top_trajectories(
    *, session: Session, limit: int, model_id: str | None = None
) -> list[Trajectory]:
    """The most reused trajectories: by hits, then by fewest validation failures, then by id."""
    query = sa.select(Trajectory).options(defer(Trajectory.states, raiseload=True))
    if model_id is not None:
        query = query.where(Trajectory.model_id == model_id)
    query = query.order_by(Trajectory.hits.desc(), Trajectory.failures, Trajectory.id).limit(limit)
    return list(session.scalars(query))
