"""Plan bookkeeping written off the request path: in order, batched, retried, flushed on close."""

from __future__ import annotations

import asyncio
from collections.abc import Iterable, Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from tests.waiting import wait_until
from trajcache.db import migrate
from trajcache.db.models import PlanEvent, RobotModel, Trajectory, utcnow
from trajcache.db.session import make_engine, make_sessionmaker
from trajcache.services.bookkeeping import records as plan_records
from trajcache.services.bookkeeping.records import PlanRecord, PlanRecorder


def seeded(url: str) -> tuple[sa.Engine, sessionmaker[Session]]:
    """A migrated database with one model and trajectories 1, 2 and 3."""
    migrate.upgrade(url)
    engine = make_engine(url)
    factory = make_sessionmaker(engine)
    with factory() as session:
        session.add(RobotModel(id="m", name="m", base="fixed", joint_names=["a"], urdf="-"))
        for i in (1, 2, 3):
            row = Trajectory(model_id="m", source="sim")
            row.set_states([[0.0], [float(i)]])
            session.add(row)
        session.commit()
    return engine, factory


@pytest.fixture
def sessions(database_url: str) -> Iterator[sessionmaker[Session]]:
    engine, factory = seeded(database_url)
    yield factory
    engine.dispose()


@pytest.fixture
def engine(sessions: sessionmaker[Session]) -> sa.Engine:
    bind: sa.Engine = sessions.kw["bind"]
    return bind


def record(served: int | None, failed: tuple[int, ...] = (), robot: str = "r1") -> PlanRecord:
    event = {
        "robot_id": robot,
        "model_id": "m",
        "scene_hash": "h",
        "status": "success" if served else "miss",
        "source": "cache" if served else None,
        "trajectory_id": served,
        "candidates_tried": len(failed) + (served is not None),
        "lookup_ms": 0.1,
        "validate_ms": 0.2,
        "plan_ms": 0.0,
        "total_ms": 0.5,
        "error": None,
    }
    return PlanRecord(utcnow(), served, failed, event)


def usage(sessions: sessionmaker[Session]) -> dict[int, tuple[int, int, int]]:
    """Trajectory id → (hits, failures, consecutive failures)."""
    with sessions() as session:
        rows = session.execute(
            sa.select(Trajectory.id, Trajectory.hits, Trajectory.failures,
                      Trajectory.consecutive_failures)
        )  # fmt: skip
        return {r[0]: (r[1], r[2], r[3]) for r in rows}


def events(sessions: sessionmaker[Session]) -> list[PlanEvent]:
    with sessions() as session:
        return list(session.execute(sa.select(PlanEvent).order_by(PlanEvent.id)).scalars())


def test_records_are_written_in_order_with_the_counters_of_synchronous_writes(
    engine: sa.Engine, sessions: sessionmaker[Session]
) -> None:
    recorder = PlanRecorder(engine, linger_s=0.05)  # long linger: one batch holds them all
    sequence = [record(1), record(2, (1,)), record(None, (1, 3)), record(3, (2,)), record(1)]
    seqs = [recorder.submit(r) for r in sequence]
    assert seqs == [1, 2, 3, 4, 5]
    assert recorder.flush(timeout=10)
    # hits, failures, failure streak as if each plan had updated the rows itself
    assert usage(sessions) == {1: (2, 2, 0), 2: (1, 1, 1), 3: (1, 1, 0)}
    got = events(sessions)
    assert [(e.status, e.trajectory_id) for e in got] == [
        ("success", 1), ("success", 2), ("miss", None), ("success", 3), ("success", 1)
    ]  # fmt: skip
    assert [e.created_at for e in got] == sorted(r.at for r in sequence)
    assert recorder.stats().written == 5 and recorder.stats().dropped == 0
    recorder.close()


def test_close_writes_everything_still_queued(
    engine: sa.Engine, sessions: sessionmaker[Session]
) -> None:
    recorder = PlanRecorder(engine, linger_s=10.0, max_batch=100)  # nothing goes on its own
    for i in range(250):
        recorder.submit(record(1 + i % 3))
    recorder.close()
    assert len(events(sessions)) == 250
    assert sum(h for h, _, _ in usage(sessions).values()) == 250
    late = recorder.submit(record(2))  # after close: written by the caller
    assert recorder.wait(late, timeout=0)
    assert len(events(sessions)) == 251


def test_blocking_on_a_record_skips_the_linger(
    engine: sa.Engine, sessions: sessionmaker[Session]
) -> None:
    recorder = PlanRecorder(engine, linger_s=30.0)
    seq = recorder.submit(record(1))
    assert recorder.wait(seq, timeout=10)  # written within 10 s: it did not linger 30 s
    recorder.close()


def test_awaiting_a_record_skips_the_linger(
    engine: sa.Engine, sessions: sessionmaker[Session]
) -> None:
    recorder = PlanRecorder(engine, linger_s=30.0)
    first = recorder.submit(record(1))
    second = recorder.submit(record(2))
    assert asyncio.run(recorder.written(first, timeout=10))  # it did not linger 30 s
    assert recorder.wait(second, timeout=0)  # both went in the same transaction
    assert [e.trajectory_id for e in events(sessions)] == [1, 2]
    recorder.close()


def test_records_nobody_waits_for_linger_then_go_together(
    engine: sa.Engine, sessions: sessionmaker[Session], monkeypatch: pytest.MonkeyPatch
) -> None:
    real_write = plan_records._write
    batches: list[int] = []

    def counted_write(bind: sa.Engine, records: Iterable[PlanRecord]) -> None:
        batch = list(records)
        batches.append(len(batch))
        real_write(bind, batch)

    monkeypatch.setattr(plan_records, "_write", counted_write)
    recorder = PlanRecorder(engine, linger_s=2.0)
    recorder.submit(record(1))
    recorder.submit(record(2))
    assert batches == [] and events(sessions) == []  # still lingering
    assert wait_until(lambda: recorder.stats().written == 2)  # then written, unasked
    assert batches == [2]  # in one transaction
    assert [e.trajectory_id for e in events(sessions)] == [1, 2]
    recorder.close()


def test_written_times_out_while_the_database_is_away(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'empty.db'}")  # no tables: every write fails
    recorder = PlanRecorder(engine, retry_max_s=0.05)
    seq = recorder.submit(record(1))
    assert not asyncio.run(recorder.written(seq, timeout=0.2))
    assert recorder.stats().pending == 1
    recorder.close(timeout=0.1)
    assert recorder.stats().dropped == 1
    engine.dispose()


def test_records_wait_in_order_until_the_database_is_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    url = f"sqlite:///{tmp_path / 'late.db'}"
    engine = make_engine(url)
    sessions = make_sessionmaker(engine)
    real_write = plan_records._write
    failed: list[int] = []

    def counted_write(bind: sa.Engine, records: Iterable[PlanRecord]) -> None:
        try:
            real_write(bind, records)
        except sa.exc.SQLAlchemyError:
            failed.append(1)
            raise

    monkeypatch.setattr(plan_records, "_write", counted_write)
    recorder = PlanRecorder(engine, retry_max_s=0.05, linger_s=0.0)
    for i in range(5):
        recorder.submit(record(None, robot=f"r{i}"))
    assert wait_until(lambda: failed)  # a write failed: the tables are not there
    assert recorder.stats().written == 0 and recorder.stats().pending == 5
    migrate.upgrade(url)  # the database comes back
    assert recorder.flush(timeout=10)
    assert [e.robot_id for e in events(sessions)] == [f"r{i}" for i in range(5)]
    assert recorder.stats().dropped == 0
    recorder.close()
    engine.dispose()


def test_a_write_whose_commit_answer_was_lost_is_not_counted_twice(
    engine: sa.Engine, sessions: sessionmaker[Session], monkeypatch: pytest.MonkeyPatch
) -> None:
    real_write = plan_records._write
    lost: list[int] = []

    def commit_then_lose_the_answer(bind: sa.Engine, records: object) -> None:
        real_write(bind, records)  # type: ignore[arg-type]
        if not lost:  # the first COMMIT reaches the database, its answer does not
            lost.append(1)
            raise sa.exc.OperationalError("COMMIT", {}, Exception("server closed the connection"))

    monkeypatch.setattr(plan_records, "_write", commit_then_lose_the_answer)
    recorder = PlanRecorder(engine, retry_max_s=0.05, linger_s=0.05)
    for r in (record(1), record(2, (1,))):
        recorder.submit(r)
    assert recorder.flush(timeout=10)
    recorder.close()
    assert lost == [1]
    assert usage(sessions) == {1: (1, 1, 1), 2: (1, 0, 0), 3: (0, 0, 0)}
    assert [e.trajectory_id for e in events(sessions)] == [1, 2]
    assert recorder.stats().dropped == 0


def test_every_written_event_has_its_own_record_key(
    engine: sa.Engine, sessions: sessionmaker[Session]
) -> None:
    recorder = PlanRecorder(engine, linger_s=0.0)
    for r in (record(1), record(None), record(3)):
        recorder.submit(r)
    recorder.close()
    keys = [e.record_key for e in events(sessions)]
    assert len(keys) == 3 and None not in keys and len(set(keys)) == 3
    with pytest.raises(sa.exc.IntegrityError), engine.begin() as conn:  # the key is unique
        conn.execute(
            sa.insert(PlanEvent),
            {**record(1).event, "created_at": utcnow(), "record_key": keys[0]},
        )


def test_the_queue_is_bounded_while_the_database_is_away(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'empty.db'}")
    recorder = PlanRecorder(engine, max_pending=4, retry_max_s=0.05)
    for _ in range(10):
        recorder.submit(record(None))
    stats = recorder.stats()
    assert stats.pending <= 4 and stats.dropped >= 6
    recorder.close(timeout=0.1)
    assert recorder.stats().dropped == 10 and recorder.stats().pending == 0
    engine.dispose()


@pytest.mark.postgres
def test_a_record_the_database_rejects_is_dropped_alone(postgres_url: str) -> None:
    engine, sessions = seeded(postgres_url)  # PostgreSQL enforces column lengths
    recorder = PlanRecorder(engine, linger_s=0.05)
    recorder.submit(record(1, robot="before"))
    recorder.submit(record(2, robot="x" * 300))  # longer than robot_id's 128 characters
    recorder.submit(record(3, robot="after"))
    assert recorder.flush(timeout=10)
    assert [e.robot_id for e in events(sessions)] == ["before", "after"]
    assert recorder.stats().dropped == 1
    assert usage(sessions) == {1: (1, 0, 0), 2: (0, 0, 0), 3: (1, 0, 0)}
    recorder.close()
    engine.dispose()
