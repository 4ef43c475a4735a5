"""The replica's index store: one query per sync, shared syncs, cached key states."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa

from tests.services.hit_setup import context, count_statements, store, two_joint
from tests.waiting import CountingLock, wait_until
from trajcache.core.config import Settings
from trajcache.db.models import Trajectory
from trajcache.geometry.model.robot import RobotModel
from trajcache.services.catalog.robots import ROBOT_SCENE, put_robot
from trajcache.services.catalog.states_cache import StatesCache
from trajcache.services.catalog.trajectories import (
    NewTrajectory,
    delete_trajectory,
    store_trajectory,
)
from trajcache.services.context import ServiceContext


def robot(ctx: ServiceContext, model: RobotModel, robot_id: str = "r1") -> str:
    with ctx.sessions() as session:
        put_robot(session=session, robot_id=robot_id, model_id=model.model_id)
    return robot_id


def test_a_sync_is_one_query_and_sees_rows_and_deletions_of_another_replica(
    database_url: str,
) -> None:
    with context(database_url) as a, context(database_url) as b:
        model = two_joint(a)
        kept = store(a, model, [[0.0, 0.0], [1.0, 0.5]])
        with b.sessions() as session:
            index = b.indexes.index(session, model)
        assert kept in index
        gone = store(a, model, [[0.2, 0.0], [1.0, 0.5]])
        fresh = store(a, model, [[0.4, 0.0], [1.0, 0.5]])
        with a.sessions() as session:
            delete_trajectory(session=session, trajectory_id=gone)
        with b.sessions() as session, count_statements(b.engine) as statements:
            index = b.indexes.index(session, model)
        assert len(statements) == 1, statements
        assert fresh in index and kept in index and gone not in index


def test_a_rider_reads_its_row_with_the_sync_and_the_index_then_needs_no_query(
    database_url: str,
) -> None:
    with context(database_url) as a, context(database_url) as b:
        model = two_joint(a)
        rid = robot(a, model)
        with b.sessions() as session:
            b.indexes.index(session, model)  # b has loaded the model's index
        fresh = store(a, model, [[0.4, 0.0], [1.0, 0.5]])  # committed before b's request
        before = b.indexes.syncs
        arrived = time.monotonic()
        with b.sessions() as session, count_statements(b.engine) as statements:
            row = b.indexes.read_with_sync(session, ROBOT_SCENE, {"robot_id": rid}, arrived=arrived)
            index = b.indexes.index(session, model, arrived=arrived)
        assert len(statements) == 1, statements
        assert b.indexes.syncs == before + 1
        assert row is not None and row[0] == model.model_id
        assert fresh in index
        with b.sessions() as session:
            ghost = {"robot_id": "ghost"}
            assert (
                b.indexes.read_with_sync(session, ROBOT_SCENE, ghost, arrived=time.monotonic())
                is None
            )
        with b.sessions() as session:  # a later request syncs again (interval 0)
            b.indexes.index(session, model)
        assert b.indexes.syncs == before + 3
        with b.sessions() as session:  # so does a later one in a reused session
            arrived = time.monotonic()
            b.indexes.read_with_sync(session, ROBOT_SCENE, {"robot_id": rid}, arrived=arrived)
            b.indexes.index(session, model, arrived=arrived)
            assert wait_until(lambda: time.monotonic() > b.indexes._synced_from)  # a later arrival
            b.indexes.index(session, model)
        assert b.indexes.syncs == before + 5


def test_a_rider_alone_is_read_when_no_sync_is_due(database_url: str) -> None:
    with context(database_url, index_sync_interval_s=60.0) as ctx:
        model = two_joint(ctx)
        rid = robot(ctx, model)
        with ctx.sessions() as session:
            ctx.indexes.index(session, model)
        before = ctx.indexes.syncs
        with ctx.sessions() as session, count_statements(ctx.engine) as statements:
            arrived = time.monotonic()
            row = ctx.indexes.read_with_sync(
                session, ROBOT_SCENE, {"robot_id": rid}, arrived=arrived
            )
            ctx.indexes.index(session, model, arrived=arrived)
        assert ctx.indexes.syncs == before
        assert len(statements) == 1 and "trajectory_tombstones" not in statements[0]
        assert row is not None and row[0] == model.model_id


def test_every_call_syncs_at_interval_zero_and_not_within_the_interval(database_url: str) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        with ctx.sessions() as session:
            ctx.indexes.index(session, model)
            before = ctx.indexes.syncs
            ctx.indexes.index(session, model)
            ctx.indexes.index(session, model)
        assert ctx.indexes.syncs == before + 2
    with context(database_url, index_sync_interval_s=60.0) as ctx, ctx.sessions() as session:
        ctx.indexes.index(session, model)
        before = ctx.indexes.syncs
        ctx.indexes.index(session, model)
        assert ctx.indexes.syncs == before


def test_requests_that_arrive_during_a_sync_share_the_next_one(tmp_path: Path) -> None:
    with context(f"sqlite:///{tmp_path / 'coalesce.db'}") as ctx:
        model = two_joint(ctx)
        with ctx.sessions() as session:
            ctx.indexes.index(session, model)
        before = ctx.indexes.syncs
        asked = threading.Barrier(7)
        done: list[int] = []

        def request() -> None:
            with ctx.sessions() as session:
                asked.wait()
                index = ctx.indexes.index(session, model)
                done.append(len(index))

        lock = ctx.indexes._lock = CountingLock()  # type: ignore[assignment]
        with lock:  # a sync is running: every request arrives during it
            threads = [threading.Thread(target=request) for _ in range(6)]
            for t in threads:
                t.start()
            asked.wait()
            assert wait_until(lambda: lock.asked == 1 + 6)  # all six wait for the lock
            stored = store(ctx, model, [[0.0, 0.0], [1.0, 0.5]])  # committed before they run
        for t in threads:
            t.join()
        assert ctx.indexes.syncs == before + 1  # one sync served all six
        assert done == [1] * 6  # the shared sync began after the commit: all six see the row
        with ctx.sessions() as session:
            assert stored in ctx.indexes.index(session, model)


@pytest.mark.postgres
def test_a_row_committed_after_a_higher_id_is_still_picked_up(postgres_url: str) -> None:
    """PostgreSQL hands out ids before commit: a lower id can become visible later (a gap)."""
    with context(postgres_url) as ctx:
        model = two_joint(ctx)
        with ctx.sessions() as session:
            ctx.indexes.index(session, model)
        slow = ctx.sessions()
        early, _ = store_trajectory(  # ids (trajectory and log row) taken, not committed
            session=slow,
            settings=Settings(),
            compute_quality=False,
            commit=False,
            trajectory=NewTrajectory(
                model=model, states=np.array([[0.3, 0.0], [1.0, 0.5]]), source="sim"
            ),
        )
        later = store(ctx, model, [[0.6, 0.0], [1.0, 0.5]])
        assert later > early
        with ctx.sessions() as session:
            index = ctx.indexes.index(session, model)
        assert later in index and early not in index
        slow.commit()
        slow.close()
        with ctx.sessions() as session:
            assert early in ctx.indexes.index(session, model)


def test_key_states_are_loaded_once_and_dropped_with_their_tombstone(database_url: str) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        states = [[0.0, 0.0], [0.5, 0.2], [1.0, 0.5]]
        first = store(ctx, model, states)
        with ctx.sessions() as session:
            ctx.indexes.index(session, model)
            with count_statements(ctx.engine) as statements:
                loaded = ctx.indexes.states(session, [first, 999_999])
            assert len(statements) == 1
            assert set(loaded) == {first} and np.array_equal(loaded[first], states)
            assert not loaded[first].flags.writeable
            with count_statements(ctx.engine) as statements:
                again = ctx.indexes.states(session, [first])
            assert statements == [] and again[first] is loaded[first]
        with ctx.sessions() as session:
            delete_trajectory(session=session, trajectory_id=first)
        with ctx.sessions() as session:
            ctx.indexes.index(session, model)  # reads the tombstone
            assert ctx.indexes.states(session, [first]) == {}
            assert session.scalar(sa.select(sa.func.count()).select_from(Trajectory)) == 0


def test_the_states_cache_is_bounded_by_bytes() -> None:
    cache = StatesCache(max_bytes=3 * 160)  # room for three 10×2 float64 arrays
    arrays = {i: np.full((10, 2), float(i)) for i in range(5)}
    for i, a in arrays.items():
        cache.put(i, a)
    found, missing = cache.get_many(range(5))
    assert sorted(found) == [2, 3, 4] and missing == [0, 1]
    cache.get_many([2])  # 2 is now the most recently used
    cache.put(5, np.zeros((10, 2)))
    found, missing = cache.get_many(range(6))
    assert sorted(found) == [2, 4, 5]
    big = np.zeros((100, 2))
    assert cache.put(9, big) is big and cache.get_many([9]) == ({}, [9])  # larger than it all
    cache.discard(2)
    assert len(cache) == 2


def stored_with_log_id(
    ctx: ServiceContext, model: RobotModel, states: list[list[float]]
) -> tuple[int, int]:
    """A trajectory stored and committed, and the id of its commit-log row."""
    logged: list[int] = []
    with ctx.sessions() as session:
        trajectory_id, created = store_trajectory(
            session=session,
            settings=Settings(),
            compute_quality=False,
            commit_ids=logged,
            trajectory=NewTrajectory(
                model=model, states=np.asarray(states, dtype=float), source="sim"
            ),
        )
    assert created and len(logged) == 1
    return trajectory_id, logged[0]


def test_a_stored_trajectory_is_indexed_at_once_and_no_sync_reads_it_again(
    database_url: str,
) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        with ctx.sessions() as session:
            index = ctx.indexes.index(session, model)
        states = [[0.0, 0.0], [0.5, 0.2], [1.0, 0.5]]
        trajectory_id, commit_id = stored_with_log_id(ctx, model, states)
        ctx.indexes.add_stored(model.model_id, trajectory_id, commit_id, np.array(states))
        assert trajectory_id in index  # before any sync
        assert ctx.indexes._commits.hwm == commit_id
        with ctx.sessions() as session, count_statements(ctx.engine) as statements:
            cached = ctx.indexes.states(session, [trajectory_id])
        assert statements == [] and np.array_equal(cached[trajectory_id], states)
        with ctx.sessions() as session:  # its deletion still reaches the index, as a tombstone
            delete_trajectory(session=session, trajectory_id=trajectory_id)
            assert trajectory_id not in ctx.indexes.index(session, model)


def test_a_stored_trajectory_that_a_sync_read_and_dropped_is_not_indexed_again(
    database_url: str,
) -> None:
    with context(database_url) as a, context(database_url) as b:
        model = two_joint(a)
        with a.sessions() as session:
            index = a.indexes.index(session, model)
        states = [[0.0, 0.0], [1.0, 0.5]]
        trajectory_id, commit_id = stored_with_log_id(a, model, states)
        with b.sessions() as session:  # another replica deletes it at once
            delete_trajectory(session=session, trajectory_id=trajectory_id)
        with a.sessions() as session:  # a's sync reads its log row and its tombstone
            a.indexes.index(session, model)
        a.indexes.add_stored(model.model_id, trajectory_id, commit_id, np.array(states))
        assert trajectory_id not in index
        with a.sessions() as session:
            assert trajectory_id not in a.indexes.index(session, model)


def test_a_stored_trajectory_whose_log_row_is_a_gap_is_indexed_and_the_gap_closed(
    database_url: str,
) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        with ctx.sessions() as session:
            index = ctx.indexes.index(session, model)
        states = [[0.0, 0.0], [1.0, 0.5]]
        trajectory_id, commit_id = stored_with_log_id(ctx, model, states)
        stream = ctx.indexes._commits
        stream.advance([commit_id + 1], time.monotonic())  # a sync passed it while in flight
        assert commit_id in stream.gaps
        ctx.indexes.add_stored(model.model_id, trajectory_id, commit_id, np.array(states))
        assert trajectory_id in index and commit_id not in stream.gaps
