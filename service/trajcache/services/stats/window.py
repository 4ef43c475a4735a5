"""Plan statistics over a time window: totals, groups, a time series and the time saved.

The time series spans the data, not the whole window: it runs from the window's first event
(at least the last minute; the whole window when it holds none) to now, in buckets chosen from
that span, so a young service is charted over its lifetime rather than as one dot.

Counts and sums are exact. Percentiles come from log-spaced histograms and are within
`histograms.MAX_RELATIVE_ERROR` (5.9 %) of the exact value. Windows whose buckets are an hour or
longer read whole hours from the hourly rollups and only the partial hours at either end from
the events; shorter windows read their events.

Groups by robot are keyed by the robot id and the requester together: a seed job's requests
(robot id `seed-job-<id>`, requester `seed_job`) are never merged with a robot of that name.

Definitions: a hit is a trajectory served from the cache; a planner call is a request that
reached the fallback planner (whether it found a path, failed or could not run); failures are
requests that ended `failure` or `error`; misses ended without planning; refusals were not
answered (a 4xx of a plan route, `services.bookkeeping.refusals`): they are counted on their own,
not among the requests, the hit rate or the latencies; `repaired` requests
were served a cached path whose failing stretch the planner replaced (planner calls too, but not
in the median planning time: a repair plans a stretch only). Lookup and validation
percentiles are over all requests, planning percentiles over planner calls.

Time saved: each hit is credited with the median planning time of the successful planner calls
for its model in the window. A model without any in the window has no estimate: its hits are
credited nothing and counted as `uncredited_hits`, so the figure is never overstated.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np
import numpy.typing as npt
from sqlalchemy.orm import Session

from trajcache.services.errors import InvalidInputError
from trajcache.services.stats import histograms
from trajcache.services.stats.event_rows import (
    ANY,
    EventFilter,
    EventRows,
    ObjArray,
    codes,
    fetch_events,
    fetch_rollups,
    first_event_at,
)
from trajcache.services.stats.events import REQUESTERS
from trajcache.services.stats.rollups import (
    ROLLUP_S,
    floor_hour,
    heal_rollups,
    refresh_rollups,
)

GROUP_BY = ("robot", "model", "source")
MAX_WINDOW_S = 366 * 86400
WINDOW_PATTERN = r"^ *([0-9]{1,6}) *([mhd]) *$"  # also the API document's (an ECMA regex)
_WINDOW = re.compile(WINDOW_PATTERN)
_UNIT_S = {"m": 60, "h": 3600, "d": 86400}
# (longest window, bucket): about 60 to 180 buckets per window.
_BUCKETS = (
    (5 * 60, 5),
    (15 * 60, 15),
    (3 * 3600, 60),
    (12 * 3600, 300),
    (7 * 86400, 3600),
    (30 * 86400, 6 * 3600),
    (90 * 86400, 86400),
)
QUANTILES = (0.5, 0.95, 0.99)
# The time series spans the data, not the whole window: a service that started ten minutes ago
# is charted over those ten minutes (15-second buckets), not as one dot in a 24-hour window.
MIN_SPAN_S = 60

HIT, PLANNED, MISS, FAILURE, ERROR, REPAIRED, REFUSED, OTHER = range(8)
PLANNER_CALLS = (PLANNED, REPAIRED, FAILURE, ERROR)
_METRICS = histograms.METRICS
_PLAN = _METRICS.index("plan")


def parse_window(text: str) -> int:
    """`30m`, `24h`, `7d` → seconds; anything else, or longer than a year, is a 422."""
    match = _WINDOW.fullmatch(text)
    seconds = int(match[1]) * _UNIT_S[match[2]] if match else 0
    if not match or not 60 <= seconds <= MAX_WINDOW_S:
        raise InvalidInputError(
            f"query.window: {text!r} is not a window like 30m, 24h or 7d (1m to 366d)"
        )
    return seconds


def bucket_seconds(window_s: int) -> int:
    """The time-series bucket for a span of time (a whole number of hours beyond 12 h)."""
    return next((b for longest, b in _BUCKETS if window_s <= longest), 7 * 86400)


@dataclass(frozen=True)
class Latency:
    """Time spent in one step: the sum and percentiles (ms); None without any value."""

    sum_ms: float
    p50: float | None
    p95: float | None
    p99: float | None


@dataclass(frozen=True)
class Metrics:
    """The statistics of a set of plan requests."""

    requests: int
    hits: int
    repaired: int
    planner_calls: int
    misses: int
    failures: int
    refusals: int
    hit_rate: float | None
    time_saved_ms: float
    uncredited_hits: int
    lookup_ms: Latency
    validate_ms: Latency
    plan_ms: Latency
    total_ms: Latency


@dataclass(frozen=True)
class ModelBasis:
    """How one model's hits were credited: the median planning time they were worth."""

    model_id: str
    hits: int
    planner_calls: int
    median_plan_ms: float | None


@dataclass(frozen=True)
class Group:
    """The statistics of one robot, model or source; a robot's group says who it is."""

    key: str
    requester: str | None  # "robot" or "seed_job" when grouped by robot; None otherwise
    metrics: Metrics


@dataclass(frozen=True)
class PlanStats:
    """Statistics of a window: totals, one entry per group, one per time bucket."""

    since: datetime
    until: datetime
    window_s: int
    bucket_s: int
    group_by: str
    totals: Metrics
    groups: list[Group]
    series: list[tuple[datetime, Metrics]]
    time_saved_basis: list[ModelBasis]


def _check_query(group_by: str, requester: str | None) -> None:
    if group_by not in GROUP_BY:
        raise InvalidInputError(f"query.group_by: {group_by!r} is not one of {GROUP_BY}")
    if requester is not None and requester not in REQUESTERS:
        raise InvalidInputError(f"query.requester: {requester!r} is not one of {REQUESTERS}")


def plan_stats(
    *,
    session: Session,
    window_s: int,
    group_by: str = "robot",
    filters: EventFilter = ANY,
    now: datetime | None = None,
) -> PlanStats:
    """Statistics of the plan requests of the last `window_s` seconds that pass `filters`,
    grouped by `group_by`."""
    _check_query(group_by, filters.requester)
    until = now or datetime.now(UTC)
    since = until - timedelta(seconds=window_s)
    span_s, start = _data_span(session, since, until, filters)
    bucket_s = bucket_seconds(span_s)
    rows = _window_rows(session, since, until, bucket_s, filters)

    category = categories(rows.status, rows.source)
    models, model = codes(rows.model)
    medians, planned = _median_plan_ms(rows, category, model, len(models))
    keys, requesters, group = _group_codes(rows, group_by)
    first = int(start // bucket_s) * bucket_s  # the bucket of the first event (not before it)
    slots = (math.ceil(until.timestamp()) - 1 - first) // bucket_s + 1
    slot = np.clip((rows.t - first) // bucket_s, 0, slots - 1)

    groups = _accumulate(rows, category, group, len(keys), model, len(models))
    by_group = _metrics(groups, medians)
    totals = _metrics(groups.total(), medians)
    by_slot = _metrics(_accumulate(rows, category, slot, slots, model, len(models)), medians)
    order = sorted(
        range(len(keys)),
        key=lambda i: (-by_group[i].requests, str(keys[i]), str(requesters[i])),
    )
    is_hit = category == HIT
    hits = np.bincount(model[is_hit], weights=rows.n[is_hit], minlength=len(models))
    return PlanStats(
        since=since,
        until=until,
        window_s=window_s,
        bucket_s=bucket_s,
        group_by=group_by,
        totals=totals[0],
        groups=[
            Group(str(keys[i]) if keys[i] is not None else "none", requesters[i], by_group[i])
            for i in order
        ],
        series=[
            (datetime.fromtimestamp(first + i * bucket_s, UTC), by_slot[i]) for i in range(slots)
        ],
        time_saved_basis=[
            ModelBasis(str(m), int(hits[i]), int(planned[i]), _number(medians[i]))
            for i, m in enumerate(models)
        ],
    )


def _data_span(s: Session, since: datetime, until: datetime, f: EventFilter) -> tuple[int, float]:
    """Whole seconds the time series covers, and its start (POSIX): from the window's first
    event to `until`, at least `MIN_SPAN_S`, at most the window (all of it without events)."""
    window_s, end = round((until - since).total_seconds()), until.timestamp()
    first = first_event_at(s, since, until, f)
    start = end - window_s if first is None else min(first.timestamp(), end - MIN_SPAN_S)
    start = max(end - window_s, start)
    return math.ceil(end - start), start


def categories(status: npt.NDArray[np.object_], source: npt.NDArray[np.object_]) -> np.ndarray:
    """Each row's category (HIT, PLANNED, MISS, FAILURE, ERROR, REPAIRED, REFUSED, OTHER) from
    status and source."""
    success = status == "success"
    return np.select(
        [
            success & (source == "cache"),
            success & (source == "planner"),
            status == "miss",
            status == "failure",
            status == "error",
            success & (source == "repaired"),
            status == "refused",
        ],
        [HIT, PLANNED, MISS, FAILURE, ERROR, REPAIRED, REFUSED],
        OTHER,
    ).astype(np.int64)


def _window_rows(
    session: Session,
    since: datetime,
    until: datetime,
    bucket_s: int,
    filters: EventFilter,
) -> EventRows:
    """Events of [since, until), whole hours from the rollups when buckets are hours or more."""
    if bucket_s < ROLLUP_S:
        return fetch_events(session, since, until, filters)
    rolled_until = refresh_rollups(session, now=until)
    heal_rollups(session, rolled_until=rolled_until)
    first_hour = floor_hour(since)
    if first_hour < since:
        first_hour += timedelta(seconds=ROLLUP_S)
    last_hour = max(first_hour, min(floor_hour(until), rolled_until))
    return EventRows.concat(
        [
            fetch_events(session, since, first_hour, filters),
            fetch_rollups(session, first_hour, last_hour, filters),
            fetch_events(session, last_hour, until, filters),
        ]
    )


def _group_codes(rows: EventRows, group_by: str) -> tuple[ObjArray, ObjArray, np.ndarray]:
    """Each group's key and requester (None unless grouped by robot), and each row's group.

    A robot's group is the pair (robot id, requester), so a seed job and a robot that share a
    name are two groups.
    """
    if group_by != "robot":
        keys, group = codes(rows.model if group_by == "model" else rows.source)
        return keys, np.full(len(keys), None, dtype=object), group
    robots, robot = codes(rows.robot)
    requesters, requester = codes(rows.requester)
    width = max(len(requesters), 1)
    pairs, group = np.unique(robot * width + requester, return_inverse=True)
    return robots[pairs // width], requesters[pairs % width], group.reshape(-1).astype(np.int64)


def _median_plan_ms(
    rows: EventRows, category: np.ndarray, model: np.ndarray, models: int
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """Per model: the median planning time of successful planner calls (NaN: none), and their
    count."""
    row, metric, where, count = rows.entries
    pick = (metric == _PLAN) & (category[row] == PLANNED)
    flat = model[row[pick]] * histograms.NBINS + where[pick]
    hist = _count(flat, count[pick], models * histograms.NBINS).reshape(models, histograms.NBINS)
    return histograms.percentiles(hist, [0.5])[:, 0], hist.sum(axis=1)


@dataclass(frozen=True)
class _Cells:
    """Per cell (a group, a bucket or the total): counts by category, sums, histograms, hits."""

    counts: npt.NDArray[np.int64]  # (cells, categories)
    sums: npt.NDArray[np.float64]  # (cells, metrics)
    hist: npt.NDArray[np.int64]  # (cells, metrics, bins); planning: planner calls only
    hits: npt.NDArray[np.int64]  # (cells, models)

    def total(self) -> _Cells:
        """All cells as one."""
        return _Cells(
            *(a.sum(axis=0, keepdims=True) for a in (self.counts, self.sums, self.hist, self.hits))
        )


def _accumulate(
    rows: EventRows,
    category: np.ndarray,
    cell: np.ndarray,
    cells: int,
    model: np.ndarray,
    models: int,
) -> _Cells:
    """Add up the rows of each cell."""
    counts = _count(cell * (OTHER + 1) + category, rows.n, cells * (OTHER + 1))
    answered = category != REFUSED  # a refusal's time is in no sum nor percentile
    per_metric = [np.bincount(cell, weights=w * answered, minlength=cells) for w in rows.sums.T]
    sums = np.stack(per_metric, axis=1).astype(np.float64).reshape(cells, len(_METRICS))
    row, metric, where, count = rows.entries
    keep = ((metric != _PLAN) | np.isin(category[row], PLANNER_CALLS)) & answered[row]
    flat = (cell[row[keep]] * len(_METRICS) + metric[keep]) * histograms.NBINS + where[keep]
    hist = _count(flat, count[keep], cells * len(_METRICS) * histograms.NBINS)
    is_hit = category == HIT
    hits = _count(cell[is_hit] * models + model[is_hit], rows.n[is_hit], cells * models)
    return _Cells(
        counts.reshape(cells, OTHER + 1),
        sums,
        hist.reshape(cells, len(_METRICS), histograms.NBINS),
        hits.reshape(cells, models),
    )


def _metrics(cells: _Cells, medians: npt.NDArray[np.float64]) -> list[Metrics]:
    """The Metrics of each cell; hits are credited with their model's median planning time."""
    sums = cells.sums
    pct = histograms.percentiles(cells.hist, QUANTILES)
    # A single value is known exactly, and no percentile of non-negative values exceeds their sum.
    single = cells.hist.sum(axis=2) == 1
    pct = np.where(single[..., None], sums[..., None], np.minimum(pct, sums[..., None]))
    known = ~np.isnan(medians)
    saved = cells.hits[:, known] @ medians[known]
    uncredited = cells.hits[:, ~known].sum(axis=1)
    out = []
    for i, c in enumerate(cells.counts):
        requests = int(c.sum() - c[REFUSED])
        latency = [
            Latency(float(sums[i, m]), *(_number(v) for v in pct[i, m]))
            for m in range(len(_METRICS))
        ]
        out.append(
            Metrics(
                requests=requests,
                hits=int(c[HIT]),
                repaired=int(c[REPAIRED]),
                planner_calls=int(c[list(PLANNER_CALLS)].sum()),
                misses=int(c[MISS]),
                failures=int(c[FAILURE] + c[ERROR]),
                refusals=int(c[REFUSED]),
                hit_rate=float(c[HIT] / requests) if requests else None,
                time_saved_ms=float(saved[i]),
                uncredited_hits=int(uncredited[i]),
                lookup_ms=latency[0],
                validate_ms=latency[1],
                plan_ms=latency[2],
                total_ms=latency[3],
            )
        )
    return out


def _count(index: np.ndarray, weights: np.ndarray, size: int) -> npt.NDArray[np.int64]:
    """Sum of `weights` per `index` in 0…size-1, exactly (bincount sums in float64)."""
    return np.rint(np.bincount(index, weights=weights, minlength=size)).astype(np.int64)


def _number(value: float) -> float | None:
    return None if np.isnan(value) else round(float(value), 4)
