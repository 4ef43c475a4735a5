"""Statistics: histograms and windows (pure), and rollup-backed stats against brute force (DB)."""

from __future__ import annotations

import itertools
import math
import threading
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from trajcache.db.models import PlanEvent, PlanEventRollup
from trajcache.db.session import make_engine
from trajcache.services.errors import InvalidInputError
from trajcache.services.stats import histograms
from trajcache.services.stats.event_rows import ANY, EventFilter
from trajcache.services.stats.events import goal_kind_counts
from trajcache.services.stats.rollups import floor_hour, refresh_rollups
from trajcache.services.stats.window import bucket_seconds, parse_window, plan_stats

TOLERANCE = histograms.MAX_RELATIVE_ERROR + 0.01  # bin width, plus percentile definitions

# --- pure: histograms and windows -----------------------------------------------------------


def _hist(values: np.ndarray) -> np.ndarray:
    return np.bincount(histograms.bin_of(values), minlength=histograms.NBINS)


def test_histogram_percentiles_are_within_one_bin_of_exact() -> None:
    rng = np.random.default_rng(7)
    for values in (rng.lognormal(1.0, 1.2, 20_000), rng.uniform(0.01, 3000.0, 5_000)):
        got = histograms.percentiles(_hist(values), [0.5, 0.95, 0.99])
        exact = np.percentile(values, [50, 95, 99])
        assert np.all(np.abs(got - exact) / exact < TOLERANCE), (got, exact)


def test_histogram_edge_cases() -> None:
    empty = histograms.percentiles(np.zeros(histograms.NBINS, np.int64), [0.5])
    assert np.isnan(empty[0])
    one = histograms.percentiles(_hist(np.array([42.0])), [0.5, 0.99])
    assert np.all(np.abs(one - 42.0) / 42.0 < histograms.MAX_RELATIVE_ERROR)
    zeros = histograms.percentiles(_hist(np.zeros(10)), [0.5])
    assert 0.0 <= zeros[0] <= histograms.LOWEST_MS
    assert histograms.bin_of([0.0, -1.0, np.nan])[0] == 0
    assert histograms.bin_of([np.inf, 1e12]).tolist() == [histograms.NBINS - 1] * 2
    # Each bin holds exactly the values between its edges.
    inside = np.sqrt(histograms.LOWER_EDGE[1:-1] * histograms.UPPER_EDGE[1:-1])
    assert histograms.bin_of(inside).tolist() == list(range(1, histograms.NBINS - 1))


def test_histograms_encode_sparsely_and_decode_together() -> None:
    a = histograms.encode([0, 2, 3], [5, 300, 361], [1, 70_000, 2])
    b = histograms.encode([], [], [])
    c = histograms.encode([1], [0], [9])
    assert len(a) == 3 * histograms.ENTRY.itemsize and b == b""
    owner, metric, where, count = histograms.decode([a, b, c])
    assert owner.tolist() == [0, 0, 0, 2]
    assert metric.tolist() == [0, 2, 3, 1]
    assert where.tolist() == [5, 300, 361, 0]
    assert count.tolist() == [1, 70_000, 2, 9]


@pytest.mark.parametrize(
    ("text", "seconds"), [("1m", 60), ("90m", 5400), (" 24h ", 86400), ("7d", 604800)]
)
def test_parse_window(text: str, seconds: int) -> None:
    assert parse_window(text) == seconds


@pytest.mark.parametrize("text", ["", "0m", "30s", "2w", "24", "h", "-1h", "367d", "1.5h", "1e3h"])
def test_parse_window_rejects_with_a_message_naming_the_parameter(text: str) -> None:
    with pytest.raises(InvalidInputError, match=r"query\.window"):
        parse_window(text)


def test_buckets_grow_with_the_window_and_are_whole_hours_beyond_12h() -> None:
    assert bucket_seconds(60) == 5 and bucket_seconds(15 * 60) == 15
    assert bucket_seconds(3600) == 60
    assert bucket_seconds(12 * 3600) == 300
    assert bucket_seconds(24 * 3600) == 3600
    assert bucket_seconds(30 * 86400) == 6 * 3600
    assert bucket_seconds(90 * 86400) == 86400
    for window in (13 * 3600, 7 * 86400, 29 * 86400, 365 * 86400):
        assert bucket_seconds(window) % 3600 == 0
        assert 13 <= window / bucket_seconds(window) <= 180


# --- against a database ---------------------------------------------------------------------


@pytest.fixture
def sessions(migrated_url: str) -> Iterator[sessionmaker[Session]]:
    """Sessions of a migrated, empty database."""
    engine = make_engine(migrated_url, pool_size=4)
    try:
        yield sessionmaker(engine, expire_on_commit=False)
    finally:
        engine.dispose()


@dataclass
class Event:
    at: datetime
    robot: str
    model: str
    status: str
    source: str | None
    lookup: float
    validate: float
    plan: float
    requester: str = "robot"

    @property
    def total(self) -> float:
        return self.lookup + self.validate + self.plan + 0.5


KINDS = (
    ("success", "cache"),
    ("success", "planner"),
    ("miss", None),
    ("failure", None),
    ("error", None),
)


def make_events(now: datetime, count: int, hours: float, seed: int) -> list[Event]:
    """Seeded events over the last `hours`; model m-b never plans (its hits get no estimate).

    A third of r1's requests are a seed job's that shares its name (requester seed_job).
    """
    rng = np.random.default_rng(seed)
    requesters = np.random.default_rng(seed + 1000)
    events = []
    for _ in range(count):
        robot = f"r{rng.integers(0, 3)}"
        model = "m-b" if robot == "r2" else "m-a"
        kind = int(rng.choice(5, p=[0.7, 0.15, 0.06, 0.06, 0.03]))
        if model == "m-b" and kind == 1:
            kind = 0
        status, source = KINDS[kind]
        plan = 0.0 if kind in (0, 2) else float(rng.lognormal(4.0, 0.4))
        events.append(
            Event(
                at=now - timedelta(seconds=float(rng.uniform(1.0, hours * 3600))),
                robot=robot,
                model=model,
                status=status,
                source=source,
                lookup=float(rng.lognormal(-1.0, 0.5)),
                validate=float(rng.lognormal(1.5, 0.6)),
                plan=plan,
                requester="seed_job" if robot == "r1" and requesters.random() < 1 / 3 else "robot",
            )
        )
    return events


def store(session: Session, events: list[Event]) -> None:
    session.add_all(
        PlanEvent(
            created_at=e.at,
            robot_id=e.robot,
            requester=e.requester,
            model_id=e.model,
            status=e.status,
            source=e.source,
            lookup_ms=e.lookup,
            validate_ms=e.validate,
            plan_ms=e.plan,
            total_ms=e.total,
        )
        for e in events
    )
    session.commit()


def close(a: float | None, b: float, rel: float = TOLERANCE) -> bool:
    return a is not None and abs(a - b) <= rel * abs(b) + 1e-9


def check_against_brute_force(
    session: Session, events: list[Event], now: datetime, window: str
) -> None:
    stats = plan_stats(session=session, window_s=parse_window(window), now=now)
    inside = [e for e in events if stats.since <= e.at < now]
    hits = [e for e in inside if e.source == "cache"]
    planned = [e for e in inside if e.source == "planner"]
    calls = [e for e in inside if e.source == "planner" or e.status in ("failure", "error")]
    t = stats.totals
    assert t.requests == len(inside) > 0
    assert t.hits == len(hits)
    assert t.planner_calls == len(calls)
    assert t.misses == sum(e.status == "miss" for e in inside)
    assert t.failures == sum(e.status in ("failure", "error") for e in inside)
    assert t.hit_rate == pytest.approx(len(hits) / len(inside))
    assert t.lookup_ms.sum_ms == pytest.approx(sum(e.lookup for e in inside))
    assert t.plan_ms.sum_ms == pytest.approx(sum(e.plan for e in inside))
    for q, name in ((50, "p50"), (95, "p95")):
        assert close(getattr(t.validate_ms, name), np.percentile([e.validate for e in inside], q))
        assert close(getattr(t.plan_ms, name), np.percentile([e.plan for e in calls], q))
    median_a = float(np.median([e.plan for e in planned]))
    hits_a = sum(e.model == "m-a" for e in hits)
    assert close(t.time_saved_ms, hits_a * median_a)
    assert t.uncredited_hits == sum(e.model == "m-b" for e in hits) > 0
    basis = {b.model_id: b for b in stats.time_saved_basis}
    assert basis["m-b"].median_plan_ms is None and basis["m-b"].planner_calls == 0
    assert close(basis["m-a"].median_plan_ms, median_a)

    groups = {(g.key, g.requester): g.metrics for g in stats.groups}
    assert sorted(groups) == sorted({(e.robot, e.requester) for e in inside})
    assert ("r1", "seed_job") in groups and ("r1", "robot") in groups  # a pair is a group
    for pair, metrics in groups.items():
        mine = [e for e in inside if (e.robot, e.requester) == pair]
        assert metrics.requests == len(mine)
        assert metrics.hits == sum(e.source == "cache" for e in mine)
    assert sum(m.requests for _, m in stats.series) == t.requests
    assert sum(m.hits for _, m in stats.series) == t.hits
    assert sum(m.time_saved_ms for _, m in stats.series) == pytest.approx(t.time_saved_ms)
    starts = [s for s, _ in stats.series]
    first = min(e.at for e in inside)  # the series spans the data: from the first event on
    assert starts[0] <= first < starts[0] + timedelta(seconds=stats.bucket_s)
    assert stats.bucket_s == bucket_seconds(max(60, math.ceil((now - first).total_seconds())))
    assert all(b - a == timedelta(seconds=stats.bucket_s) for a, b in itertools.pairwise(starts))
    for start, metrics in stats.series:
        end = start + timedelta(seconds=stats.bucket_s)
        assert metrics.requests == sum(start <= e.at < end for e in inside)


def test_stats_match_brute_force_on_events_and_on_rollups(
    sessions: sessionmaker[Session],
) -> None:
    now = datetime.now(UTC)
    events = make_events(now, 1500, hours=30, seed=1)
    with sessions() as session:
        store(session, events)
        check_against_brute_force(session, events, now, "3h")  # events only, 1-min buckets
        check_against_brute_force(session, events, now, "24h")  # whole hours from rollups
        check_against_brute_force(session, events, now, "2d")
        rolled = session.scalar(sa.select(sa.func.sum(PlanEventRollup.requests)))
        horizon = floor_hour(now - timedelta(minutes=5))
        assert rolled == sum(e.at < horizon for e in events)


def test_a_long_window_on_a_young_service_is_charted_over_its_data(
    sessions: sessionmaker[Session],
) -> None:
    """Ten minutes of traffic in a 24-hour window: 15-second buckets over those ten minutes."""
    now = datetime(2030, 5, 6, 7, 8, 9, tzinfo=UTC)
    events = [
        Event(now - timedelta(seconds=600 - 10 * k), f"r{k % 2}", "m-a", "success", "cache",
              0.2, 1.0, 0.0)
        for k in range(60)
    ]  # fmt: skip
    with sessions() as session:
        store(session, events)
        stats = plan_stats(session=session, window_s=86400, now=now)
        empty = plan_stats(session=session, window_s=86400, now=now - timedelta(days=2))
    assert stats.since == now - timedelta(days=1) and stats.totals.requests == 60
    assert stats.bucket_s == 15
    drawn = [m for _, m in stats.series if m.requests]
    assert 38 <= len(stats.series) <= 42 and len(drawn) >= 38  # a line, not a dot
    assert sum(m.requests for m in drawn) == 60
    assert empty.bucket_s == 3600 and 24 <= len(empty.series) <= 25  # no data: the whole window


def test_the_series_starts_in_the_bucket_of_the_first_event(
    sessions: sessionmaker[Session],
) -> None:
    """The first event 0.36 s into a minute, `now` 1.65 s into one: the span, in whole seconds,
    reaches back past the minute's start, but the series starts at the event's minute."""
    now = datetime(2030, 5, 6, 16, 54, 1, 647482, tzinfo=UTC)
    first = datetime(2030, 5, 6, 13, 55, 0, 357209, tzinfo=UTC)
    events = [
        Event(first + timedelta(minutes=k), "r1", "m-a", "success", "cache", 0.2, 1.0, 0.0)
        for k in range(0, 170, 7)
    ]
    with sessions() as session:
        store(session, events)
        stats = plan_stats(session=session, window_s=3 * 3600, now=now)
    assert stats.bucket_s == 60
    start = stats.series[0][0]
    assert start <= first < start + timedelta(seconds=60)
    assert stats.series[0][1].requests == 1
    assert sum(m.requests for _, m in stats.series) == len(events)


def test_group_by_model_and_source(sessions: sessionmaker[Session]) -> None:
    now = datetime.now(UTC)
    events = make_events(now, 400, hours=20, seed=2)
    with sessions() as session:
        store(session, events)
        sources = plan_stats(session=session, window_s=86400, group_by="source").groups
        models = plan_stats(session=session, window_s=86400, group_by="model").groups
    assert {g.requester for g in sources + models} == {None}  # only a robot's group has one
    by_source = {g.key: g.metrics for g in sources}
    by_model = {g.key: g.metrics for g in models}
    assert by_source["cache"].requests == sum(e.source == "cache" for e in events)
    assert by_source["none"].requests == sum(e.source is None for e in events)
    assert by_source["planner"].time_saved_ms == 0.0
    assert by_model["m-b"].requests == sum(e.model == "m-b" for e in events)
    assert by_model["m-b"].time_saved_ms == 0.0 and by_model["m-b"].uncredited_hits > 0


def test_filters_and_an_empty_window(sessions: sessionmaker[Session]) -> None:
    now = datetime.now(UTC)
    events = make_events(now, 300, hours=10, seed=3)
    with sessions() as session:
        store(session, events)
        only = plan_stats(
            session=session, window_s=86400, now=now, filters=EventFilter(robot_id="r1")
        )
        assert only.totals.requests == sum(e.robot == "r1" for e in events)
        assert [(g.key, g.requester) for g in only.groups] == [("r1", "robot"), ("r1", "seed_job")]
        for requester in ("robot", "seed_job"):
            mine = plan_stats(
                session=session, window_s=86400, now=now, filters=EventFilter(requester=requester)
            )
            assert mine.totals.requests == sum(e.requester == requester for e in events)
        with pytest.raises(InvalidInputError, match=r"query\.requester"):
            plan_stats(
                session=session, window_s=86400, now=now, filters=EventFilter(requester="drone")
            )
        later = now + timedelta(days=2)
        empty = plan_stats(session=session, window_s=3600, now=later)
    assert empty.totals.requests == 0 and empty.totals.hit_rate is None
    assert empty.totals.lookup_ms.p50 is None and empty.groups == []
    assert len(empty.series) in (60, 61) and all(m.requests == 0 for _, m in empty.series)


def test_an_event_written_late_into_a_summarised_hour_is_counted(
    sessions: sessionmaker[Session],
) -> None:
    now = datetime.now(UTC)
    events = make_events(now, 200, hours=8, seed=4)
    with sessions() as session:
        store(session, events)
        before = plan_stats(session=session, window_s=86400, now=now).totals.requests
        late = Event(now - timedelta(hours=3), "r0", "m-a", "success", "cache", 0.2, 3.0, 0.0)
        store(session, [late])  # e.g. a replica that could not reach the database for a while
        after = plan_stats(session=session, window_s=86400, now=now).totals.requests
    assert (before, after) == (len(events), len(events) + 1)


def test_replicas_refreshing_at_once_summarise_each_hour_once(
    sessions: sessionmaker[Session],
) -> None:
    now = datetime.now(UTC)
    events = make_events(now, 600, hours=60, seed=5)
    with sessions() as session:
        store(session, events)
    errors: list[BaseException] = []
    barrier = threading.Barrier(3)

    def replica() -> None:
        try:
            with sessions() as session:
                barrier.wait()
                refresh_rollups(session, now=now)
        except BaseException as exc:  # reported below
            errors.append(exc)

    threads = [threading.Thread(target=replica) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    horizon = floor_hour(now - timedelta(minutes=5))
    with sessions() as session:
        rolled = session.scalar(sa.select(sa.func.sum(PlanEventRollup.requests)))
        again = refresh_rollups(session, now=now)
        assert session.scalar(sa.select(sa.func.sum(PlanEventRollup.requests))) == rolled
    assert rolled == sum(e.at < horizon for e in events)
    assert again == horizon


def test_requests_by_goal_kind_from_events_and_rollups(sessions: sessionmaker[Session]) -> None:
    """Every third event a pose goal, every third of unknown kind (recorded before kinds were):
    the counts over windows read from events only, and mostly from rollups, match."""
    now = datetime.now(UTC)
    with sessions() as session:
        store(session, make_events(now, 900, hours=30, seed=5))
        kind = sa.case((PlanEvent.id % 3 == 0, "pose"), (PlanEvent.id % 3 == 1, "joint"))
        session.execute(sa.update(PlanEvent).values(goal_kind=kind))
        session.execute(sa.update(PlanEvent).where(PlanEvent.id % 7 == 0).values(status="refused"))
        session.commit()
        rows = session.execute(
            sa.select(PlanEvent.created_at, PlanEvent.goal_kind, PlanEvent.status)
        ).all()
        for window in ("3h", "24h", "2d"):
            stats = plan_stats(session=session, window_s=parse_window(window), now=now)
            want = Counter(
                k or "unknown"
                for at, k, status in rows
                if stats.since <= at < stats.until and status != "refused"
            )
            got = goal_kind_counts(
                session=session, since=stats.since, until=stats.until, filters=ANY
            )
            assert got == dict(want) and set(got) == {"joint", "pose", "unknown"}, window
        assert session.scalar(sa.select(sa.func.count()).where(PlanEventRollup.goal_kind == "pose"))
