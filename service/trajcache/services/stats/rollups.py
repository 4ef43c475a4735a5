"""Hourly rollups of plan events, kept current by whoever asks for statistics.

An hour is summarised once it is `SETTLE_S` in the past (events are written off the request
path, a little after they happened): one `PlanEventRollup` row per robot and requester, model,
source, status and goal kind, with the timing sums and their histograms (a robot and a seed job
that share a name stay apart). `PlanEventRollupState.rolled_until` says how far that has gone;
replicas advance it with a compare-and-set, so each hour is summarised by exactly one of them.
An event written later than that into an hour already summarised is picked up by
`heal_rollups`, which compares event and rollup counts over the last `RECHECK_S` and summarises
again the hours that differ.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import numpy as np
import numpy.typing as npt
import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from trajcache.db.models import PlanEvent, PlanEventRollup, PlanEventRollupState
from trajcache.services.stats import histograms
from trajcache.services.stats.event_rows import EventRows, codes, epoch_seconds, fetch_events

ROLLUP_S = 3600
SETTLE_S = 300
RECHECK_S = 6 * 3600
CHUNK_S = 24 * 3600
_STATE_ID = 1


def summarise(rows: EventRows, hour_start: int) -> list[dict[str, object]]:
    """Rollup rows (column values) for events of the hours from `hour_start` (epoch s) on."""
    if not len(rows):
        return []
    hour = (rows.t - hour_start) // ROLLUP_S
    grouped = (rows.robot, rows.requester, rows.model, rows.source, rows.status, rows.goal_kind)
    columns = [codes(c) for c in grouped]
    dims = (int(hour.max()) + 1, *(len(labels) for labels, _ in columns))
    flat = np.ravel_multi_index((hour, *(inverse for _, inverse in columns)), dims)
    unique, inverse = np.unique(flat, return_inverse=True)
    groups = len(unique)
    n = np.bincount(inverse, weights=rows.n, minlength=groups).astype(np.int64)
    sums = np.stack(
        [np.bincount(inverse, weights=rows.sums[:, m], minlength=groups) for m in range(4)], axis=1
    )
    blobs = _histogram_blobs(rows, inverse, groups)
    keys = np.unravel_index(unique, dims)
    (robots, _), (requesters, _), (models, _), (sources, _), (statuses, _), (kinds, _) = columns
    return [
        {
            "bucket_start": datetime.fromtimestamp(hour_start + int(keys[0][i]) * ROLLUP_S, UTC),
            "robot_id": robots[keys[1][i]],
            "requester": requesters[keys[2][i]],
            "model_id": models[keys[3][i]],
            "source": sources[keys[4][i]],
            "status": statuses[keys[5][i]],
            "goal_kind": kinds[keys[6][i]],
            "requests": int(n[i]),
            "lookup_ms": float(sums[i, 0]),
            "validate_ms": float(sums[i, 1]),
            "plan_ms": float(sums[i, 2]),
            "total_ms": float(sums[i, 3]),
            "histograms": blobs[i],
        }
        for i in range(groups)
    ]


def _histogram_blobs(rows: EventRows, group: npt.NDArray[np.int64], groups: int) -> list[bytes]:
    """Each group's histogram entries, encoded (sparse: only the bins that have values)."""
    row, metric, where, count = rows.entries
    width = len(histograms.METRICS) * histograms.NBINS
    key = group[row] * width + metric * histograms.NBINS + where
    unique, inverse = np.unique(key, return_inverse=True)
    counts = np.bincount(inverse.reshape(-1), weights=count).astype(np.int64)
    owner, rest = np.divmod(unique, width)
    encoded = histograms.encode(rest // histograms.NBINS, rest % histograms.NBINS, counts)
    size = histograms.ENTRY.itemsize
    bounds = np.searchsorted(owner, np.arange(groups + 1)) * size
    return [encoded[bounds[i] : bounds[i + 1]] for i in range(groups)]


def floor_hour(at: datetime) -> datetime:
    """The start of the hour `at` falls in (UTC)."""
    seconds = int(at.timestamp()) // ROLLUP_S * ROLLUP_S
    return datetime.fromtimestamp(seconds, UTC)


def refresh_rollups(session: Session, *, now: datetime) -> datetime:
    """Summarise every hour that ended `SETTLE_S` before `now`; the new `rolled_until`."""
    target = floor_hour(now - timedelta(seconds=SETTLE_S))
    done = _rolled_until(session)
    if done is None:
        first = session.scalar(sa.select(sa.func.min(PlanEvent.created_at)))
        _create_state(session, floor_hour(first) if first is not None else target)
        done = _rolled_until(session)
        assert done is not None
    while done < target:
        upcoming = session.scalar(
            sa.select(sa.func.min(PlanEvent.created_at)).where(
                PlanEvent.created_at >= done, PlanEvent.created_at < target
            )
        )
        end = target if upcoming is None else min(floor_hour(upcoming) + _CHUNK, target)
        if not _advance(session, done, end):  # another replica got there first
            session.rollback()
            done = _rolled_until(session) or done
            continue
        _insert(session, fetch_events(session, done, end), done)
        session.commit()
        done = end
    return done


def heal_rollups(session: Session, *, rolled_until: datetime) -> list[datetime]:
    """Summarise again the recent hours whose rollups miss events written late; those hours."""
    since = rolled_until - timedelta(seconds=RECHECK_S)
    stale = _stale_hours(session, since, rolled_until)
    if not stale:
        return []
    # Lock the state row, then look again: another replica may be healing the same hours.
    session.execute(
        sa.update(PlanEventRollupState)
        .where(PlanEventRollupState.id == _STATE_ID)
        .values(rolled_until=PlanEventRollupState.rolled_until)
    )
    stale = _stale_hours(session, since, rolled_until)
    for hour in stale:
        end = hour + timedelta(seconds=ROLLUP_S)
        session.execute(
            sa.delete(PlanEventRollup).where(
                PlanEventRollup.bucket_start >= hour, PlanEventRollup.bucket_start < end
            )
        )
        _insert(session, fetch_events(session, hour, end), hour)
    session.commit()
    return stale


_CHUNK = timedelta(seconds=CHUNK_S)


def _stale_hours(session: Session, since: datetime, until: datetime) -> list[datetime]:
    hour = epoch_seconds(session, PlanEvent.created_at) // ROLLUP_S
    counted = dict(
        session.execute(
            sa.select(hour, sa.func.count())
            .where(PlanEvent.created_at >= since, PlanEvent.created_at < until)
            .group_by(hour)
        ).all()
    )
    start = epoch_seconds(session, PlanEventRollup.bucket_start)
    rolled = dict(
        session.execute(
            sa.select(start, sa.func.sum(PlanEventRollup.requests))
            .where(PlanEventRollup.bucket_start >= since, PlanEventRollup.bucket_start < until)
            .group_by(start)
        ).all()
    )
    rolled = {int(k) // ROLLUP_S: int(v) for k, v in rolled.items()}
    hours = {int(k) for k in counted} | set(rolled)
    return [
        datetime.fromtimestamp(h * ROLLUP_S, UTC)
        for h in sorted(hours)
        if int(counted.get(h, 0)) != rolled.get(h, 0)
    ]


def _insert(session: Session, rows: EventRows, begin: datetime) -> None:
    values = summarise(rows, int(begin.timestamp()))
    if values:
        session.execute(sa.insert(PlanEventRollup), values)


def _rolled_until(session: Session) -> datetime | None:
    return session.scalar(
        sa.select(PlanEventRollupState.rolled_until).where(PlanEventRollupState.id == _STATE_ID)
    )


def _create_state(session: Session, start: datetime) -> None:
    dialect = session.get_bind().dialect.name
    insert = postgresql.insert if dialect == "postgresql" else sqlite.insert
    session.execute(
        insert(PlanEventRollupState)
        .values(id=_STATE_ID, rolled_until=start)
        .on_conflict_do_nothing(index_elements=["id"])
    )
    session.commit()


def _advance(session: Session, done: datetime, end: datetime) -> bool:
    result = session.execute(
        sa.update(PlanEventRollupState)
        .where(PlanEventRollupState.id == _STATE_ID, PlanEventRollupState.rolled_until == done)
        .values(rolled_until=end)
    )
    return bool(result.rowcount == 1)  # type: ignore[attr-defined]
