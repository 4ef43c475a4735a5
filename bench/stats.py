"""Statistics queries at 10⁶ plan events: GET /v1/stats, plan-event pages, usage, top trajectories.

Inserts N plan events (default 10⁶, spread over the last 7 days, 50 robots of 2 models, 90 % cache
hits) in bulk, plus cached trajectories, into a fresh SQLite file or PostgreSQL schema; then times
each statistics query as the service runs it (the service functions on one session; HTTP adds
serialisation only). The first long-window request summarises every closed hour into rollups
once ("initial rollup"); later requests read the rollups and only the partial hours from events.
For comparison, the same percentiles (window, per robot, per hour) computed exactly from the
events (PostgreSQL `percentile_cont` over grouping sets; SQLite: fetch and numpy) show what the
rollups avoid.

    python bench/stats.py [--smoke] [--database-url postgresql+psycopg://…] [--events N]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
import uuid
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db import migrate
from trajcache.db.models import PlanEvent, RobotModel, Trajectory, pack_states, utcnow
from trajcache.db.session import make_engine
from trajcache.services.stats.event_rows import epoch_seconds
from trajcache.services.stats.events import (
    PlanEventFilter,
    list_plan_events,
    top_trajectories,
    trajectory_usage,
)
from trajcache.services.stats.window import plan_stats

COLUMNS = (
    "created_at, robot_id, model_id, status, source, trajectory_id, candidates_tried, "
    "lookup_ms, validate_ms, plan_ms, total_ms"
)
KINDS = (("success", "cache"), ("success", "planner"), ("miss", None), ("failure", None))


def make_events(count: int, days: float, robots: int, trajectories: int, seed: int) -> list[Any]:
    """`count` events as rows (oldest first): hits 90 %, planner 8 %, misses 1 %, failures 1 %."""
    rng = np.random.default_rng(seed)
    now = np.datetime64(datetime.now(UTC).replace(tzinfo=None), "us")
    ages = np.sort(rng.uniform(1.0, days * 86400.0, count))[::-1]
    stamps = now - (ages * 1e6).astype("timedelta64[us]")
    text = np.char.replace(np.datetime_as_string(stamps, unit="us"), "T", " ")
    robot = rng.integers(0, robots, count)
    kind = rng.choice(4, count, p=[0.9, 0.08, 0.01, 0.01])
    lookup = rng.lognormal(-0.7, 0.5, count)
    validate = rng.lognormal(1.5, 0.6, count)
    plan = np.where(kind == 1, rng.lognormal(4.2, 0.5, count), 0.0)
    plan = np.where(kind == 3, rng.lognormal(7.5, 0.1, count), plan)
    served = np.where(kind <= 1, rng.integers(1, trajectories + 1, count), 0)
    total = lookup + validate + plan + 1.0
    return [
        (
            str(text[i]),
            f"robot-{robot[i]:03d}",
            f"model-{robot[i] % 2}",
            KINDS[kind[i]][0],
            KINDS[kind[i]][1],
            int(served[i]) or None,
            1,
            float(lookup[i]),
            float(validate[i]),
            float(plan[i]),
            float(total[i]),
        )
        for i in range(count)
    ]


def insert_events(engine: sa.Engine, rows: list[Any]) -> None:
    """Bulk insert: executemany on SQLite, COPY on PostgreSQL."""
    raw = engine.raw_connection()
    try:
        cursor = raw.cursor()
        if engine.dialect.name == "sqlite":
            marks = ", ".join("?" * 11)
            cursor.executemany(f"INSERT INTO plan_events ({COLUMNS}) VALUES ({marks})", rows)
        else:
            with cursor.copy(f"COPY plan_events ({COLUMNS}) FROM STDIN") as copy:
                for row in rows:
                    copy.write_row((row[0] + "+00", *row[1:]))
        raw.commit()
    finally:
        raw.close()


def insert_trajectories(engine: sa.Engine, count: int, seed: int) -> None:
    """Two models and `count` small trajectories with skewed hit counts."""
    rng = np.random.default_rng(seed)
    with Session(engine) as session:
        for m in range(2):
            session.add(
                RobotModel(
                    id=f"model-{m}",
                    name=f"model-{m}",
                    base="fixed",
                    joint_names=["j1", "j2"],
                    urdf="<robot name='bench'/>",
                    allowed_pairs=[],
                    config={},
                )
            )
        session.commit()
        now = utcnow()
        values = []
        for i in range(count):
            states = rng.uniform(-1, 1, (4, 2))
            row = Trajectory(model_id=f"model-{i % 2}", source="planner")
            row.set_states(states)
            values.append(
                {
                    "model_id": row.model_id,
                    "source": "planner",
                    "states": pack_states(states),
                    "n_states": 4,
                    "dof": 2,
                    "start": row.start,
                    "goal": row.goal,
                    "start_x": row.start_x,
                    "start_y": row.start_y,
                    "goal_x": row.goal_x,
                    "goal_y": row.goal_y,
                    "env": {},
                    "content_hash": row.content_hash,
                    "hits": int(rng.zipf(1.5)) % 100_000,
                    "failures": int(rng.integers(0, 5)),
                    "consecutive_failures": 0,
                    "real_validations": 0,
                    "created_at": now,
                }
            )
        session.execute(sa.insert(Trajectory), values)
        session.commit()


def timed(fn: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """Median wall time (ms) of `repeats` calls after one warm-up call, and the last result."""
    result = fn()
    times = []
    for _ in range(repeats):
        began = time.perf_counter()
        result = fn()
        times.append((time.perf_counter() - began) * 1e3)
    return statistics.median(times), result


def raw_equivalent(session: Session, since: datetime) -> Any:
    """What /v1/stats computes, straight from the events: exact p50/p95/p99 of the four timings
    for the window, per robot and per hour (PostgreSQL: `percentile_cont` over grouping sets;
    SQLite has no percentile function: fetch and numpy). The baseline the rollups replace."""
    e = PlanEvent
    metrics = (e.lookup_ms, e.validate_ms, e.plan_ms, e.total_ms)
    if session.get_bind().dialect.name == "postgresql":
        quantiles = sa.literal([0.5, 0.95, 0.99], sa.ARRAY(sa.Float))
        hour = sa.func.date_trunc("hour", e.created_at)
        return session.execute(
            sa.select(
                e.robot_id,
                hour,
                sa.func.count(),
                *(sa.func.percentile_cont(quantiles).within_group(m) for m in metrics),
            )
            .where(e.created_at >= since)
            .group_by(sa.func.grouping_sets(sa.tuple_(), sa.tuple_(e.robot_id), sa.tuple_(hour)))
        ).all()
    query = sa.select(e.robot_id, epoch_seconds(session, e.created_at), *metrics).where(
        e.created_at >= since
    )
    rows = session.connection().execute(query).all()
    robot = np.array([r[0] for r in rows])
    hour = np.array([r[1] for r in rows]) // 3600
    values = np.array([r[2:] for r in rows], dtype=float)
    out = [np.percentile(values, [50, 95, 99], axis=0)]
    for keys in (robot, hour):
        order = np.argsort(keys, kind="stable")
        ordered = keys[order]
        bounds = np.flatnonzero(ordered[1:] != ordered[:-1]) + 1
        for part in np.split(values[order], bounds):
            out.append(np.percentile(part, [50, 95, 99], axis=0))
    return out


def schema_url(url: str) -> tuple[str, str | None]:
    """For PostgreSQL, a fresh schema to work in (dropped afterwards)."""
    if not url.startswith("postgresql"):
        return url, None
    schema = f"bench_stats_{uuid.uuid4().hex[:8]}"
    engine = sa.create_engine(url, isolation_level="AUTOCOMMIT")
    with engine.connect() as conn:
        conn.execute(sa.text(f'CREATE SCHEMA "{schema}"'))
    engine.dispose()
    joiner = "&" if "?" in url else "?"
    return f"{url}{joiner}options=-csearch_path%3D{schema}", schema


def drop_schema(url: str, schema: str) -> None:
    engine = sa.create_engine(url, isolation_level="AUTOCOMMIT")
    with engine.connect() as conn:
        conn.execute(sa.text(f'DROP SCHEMA "{schema}" CASCADE'))
    engine.dispose()


def run(url: str, events: int, trajectories: int, repeats: int, seed: int) -> dict[str, float]:
    """Fill the database, then time every query; their medians (ms) by name."""
    migrate.upgrade(url)
    engine = make_engine(url, pool_size=2)
    try:
        began = time.perf_counter()
        fill(engine, events, trajectories, seed)
        figures = {"insert_s": time.perf_counter() - began}
        with Session(engine) as session:
            figures.update(time_queries(session, repeats))
    finally:
        engine.dispose()
    return figures


def fill(engine: sa.Engine, events: int, trajectories: int, seed: int) -> None:
    """Insert the trajectories and a week of events (and ANALYZE on PostgreSQL)."""
    insert_trajectories(engine, trajectories, seed)
    insert_events(engine, make_events(events, 7.0, 50, trajectories, seed))
    if engine.dialect.name == "postgresql":
        with engine.connect() as conn:
            conn.execute(sa.text("ANALYZE"))
            conn.commit()


def time_queries(session: Session, repeats: int) -> dict[str, float]:
    """The first roll-up's time, then each query's median (ms) over `repeats` runs."""
    figures: dict[str, float] = {}
    began = time.perf_counter()
    plan_stats(session=session, window_s=7 * 86400)
    figures["initial_rollup_ms"] = (time.perf_counter() - began) * 1e3
    for label, window, group_by in (
        ("stats_1h", 3600, "robot"),
        ("stats_24h", 86400, "robot"),
        ("stats_7d", 7 * 86400, "robot"),
        ("stats_7d_by_model", 7 * 86400, "model"),
        ("stats_30d_by_source", 30 * 86400, "source"),
    ):
        figures[label], stats = timed(
            lambda w=window, g=group_by: plan_stats(session=session, window_s=w, group_by=g),
            repeats,
        )
        if label == "stats_7d":
            figures["requests_in_7d"] = stats.totals.requests
    figures["events_first_page"], page = timed(
        lambda: list_plan_events(session=session, limit=100), repeats
    )
    cursor = page.next_cursor
    for _ in range(50):  # 5,000 events deep
        cursor = list_plan_events(session=session, limit=100, cursor=cursor).next_cursor
    figures["events_page_51"], _ = timed(
        lambda: list_plan_events(session=session, limit=100, cursor=cursor), repeats
    )
    figures["events_by_robot"], _ = timed(
        lambda: list_plan_events(
            session=session, limit=100, filters=PlanEventFilter(robot_id="robot-007")
        ),
        repeats,
    )
    figures["events_failures"], _ = timed(
        lambda: list_plan_events(
            session=session, limit=100, filters=PlanEventFilter(status="failure")
        ),
        repeats,
    )
    figures["trajectory_usage"], _ = timed(
        lambda: trajectory_usage(session=session, trajectory_id=42), repeats
    )
    figures["top_trajectories"], _ = timed(
        lambda: top_trajectories(session=session, limit=10), repeats
    )
    since = datetime.now(UTC) - timedelta(days=7)
    figures["raw_events_equivalent_7d"], _ = timed(
        lambda: raw_equivalent(session, since), max(1, repeats // 3)
    )
    return figures


def main() -> None:
    """Run the benchmark and print the table and the JSON line."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--smoke", action="store_true", help="tiny run for CI")
    parser.add_argument("--database-url", default=None, help="default: a temporary SQLite file")
    parser.add_argument("--events", type=int, default=None, help="plan events (default 10^6)")
    parser.add_argument("--seed", type=int, default=8)
    args = parser.parse_args()
    events = args.events or (20_000 if args.smoke else 1_000_000)
    trajectories = 500 if args.smoke else 20_000
    repeats = 3 if args.smoke else 7

    with tempfile.TemporaryDirectory() as tmp:
        url = args.database_url or f"sqlite:///{Path(tmp) / 'stats.db'}"
        work_url, schema = schema_url(url)
        try:
            figures = run(work_url, events, trajectories, repeats, args.seed)
        finally:
            if schema is not None:
                drop_schema(url, schema)

    database = "postgresql" if url.startswith("postgresql") else "sqlite"
    print(f"{events:,} plan events over 7 days, {trajectories:,} trajectories, {database}")
    print(f"{'query':<34}{'median ms':>12}")
    for name, value in figures.items():
        if name.endswith("_ms") or name.startswith(("stats_", "events_", "traj", "top", "raw")):
            print(f"{name:<34}{value:>12.1f}")
    print(f"{'insert (s)':<34}{figures['insert_s']:>12.1f}")
    print(
        json.dumps(
            {
                **{k: round(v, 2) for k, v in figures.items()},
                "events": events,
                "database": database,
                "smoke": args.smoke,
            }
        )
    )


if __name__ == "__main__":
    main()
