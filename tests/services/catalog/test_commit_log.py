"""Replicas sync through the trajectory commit log: stored and imported rows, an open import,
commits out of order, and a log pruned past a lagging replica."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from tests.services.hit_setup import context, count_statements, store, two_joint
from trajcache.db.commit_log import prune_commit_log, prune_tombstones
from trajcache.db.models import Trajectory, TrajectoryCommit, TrajectoryTombstone
from trajcache.geometry.model.robot import RobotModel
from trajcache.services.catalog.trajectories import delete_trajectory, new_row_values
from trajcache.services.context import ServiceContext
from trajcache.services.maintenance.bulk_insert import BatchWriter

LATER = datetime.now(UTC) + timedelta(days=1)


def import_values(model: RobotModel, k: int) -> dict[str, Any]:
    """The columns of the `k`-th imported row (distinct states for each `k`)."""
    states = np.array([[0.001 * (k % 1000), 0.3 + 0.001 * (k // 1000)], [1.0, 0.5]])
    counters = {"hits": 0, "failures": 0, "consecutive_failures": 0, "real_validations": 0}
    return {
        **new_row_values(model, states, source="import"),
        **counters,
        "created_at": datetime.now(UTC),
        "quality_pending": False,
    }


def write_import(session: Session, model: RobotModel, count: int) -> BatchWriter:
    """Queue and insert `count` rows in `session`'s transaction, in batches of 500."""
    writer = BatchWriter(session, batch_rows=500)
    for k in range(count):
        writer.add(import_values(model, k))
    writer.flush()
    assert writer.inserted == count
    return writer


def stored_ids(ctx: ServiceContext) -> set[int]:
    with ctx.sessions() as session:
        return {int(i) for i in session.scalars(sa.select(Trajectory.id))}


def index_ids(ctx: ServiceContext, model: RobotModel) -> set[int]:
    with ctx.sessions() as session:
        return {int(i) for i in ctx.indexes.index(session, model).ids()}


def test_stored_and_imported_rows_reach_the_next_sync_of_another_replica(
    database_url: str,
) -> None:
    with context(database_url) as a, context(database_url) as b:
        model = two_joint(a)
        before = store(a, model, [[0.0, 0.0], [1.0, 0.5]])
        assert index_ids(b, model) == {before}  # loaded from the table
        stored = store(a, model, [[0.5, 0.0], [1.0, 0.5]])
        with a.sessions() as session:
            write_import(session, model, 1200).finish()
            session.commit()
        with a.sessions() as session:
            logged = session.execute(sa.select(TrajectoryCommit.first_id, TrajectoryCommit.last_id))
            assert len(logged.all()) == 1 + 1 + 3  # one per store, one per batch of the import
        with b.sessions() as session, count_statements(b.engine) as statements:
            index = b.indexes.index(session, model)
        assert len(statements) == 1, statements
        assert stored in index
        assert index_ids(b, model) == stored_ids(a) and len(stored_ids(a)) == 2 + 1200
        with a.sessions() as session:  # a logged row deleted since is not added back
            delete_trajectory(session=session, trajectory_id=stored)
        assert stored not in index_ids(b, model)


def test_a_log_row_whose_trajectories_are_gone_still_advances_the_mark(database_url: str) -> None:
    with context(database_url) as a, context(database_url) as b:
        model = two_joint(a)
        index_ids(b, model)
        gone = store(a, model, [[0.2, 0.0], [1.0, 0.5]])
        with a.sessions() as session:
            delete_trajectory(session=session, trajectory_id=gone)
        kept = store(a, model, [[0.4, 0.0], [1.0, 0.5]])
        assert index_ids(b, model) == {kept}
        with b.sessions() as session:
            top = session.scalar(sa.select(sa.func.max(TrajectoryCommit.id)))
        assert b.indexes._commits.hwm == top and not b.indexes._commits.gaps


def test_a_log_pruned_past_a_lagging_replica_makes_it_reload(database_url: str) -> None:
    with context(database_url) as a, context(database_url) as b:
        model = two_joint(a)
        first = store(a, model, [[0.0, 0.0], [1.0, 0.5]])
        assert index_ids(b, model) == {first}
        missed = [store(a, model, [[0.1 * k, 0.0], [1.0, 0.5]]) for k in range(1, 4)]
        with a.sessions() as session:  # b slept longer than the retention
            assert prune_commit_log(session, before=LATER) == 3  # the newest row stays
            assert session.scalar(sa.select(sa.func.count()).select_from(TrajectoryCommit)) == 1
        assert b.indexes.reloads == 0
        assert index_ids(b, model) == {first, *missed}
        assert b.indexes.reloads == 1
        fresh = store(a, model, [[0.5, 0.5], [1.0, 0.5]])
        assert index_ids(b, model) == {first, *missed, fresh}
        assert b.indexes.reloads == 1  # a replica in step does not reload
        with a.sessions() as session:  # nothing left to prune but the newest row
            assert prune_commit_log(session, before=LATER) == 1
        assert index_ids(a, model) == index_ids(b, model) == {first, *missed, fresh}
        assert (a.indexes.reloads, b.indexes.reloads) == (0, 1)  # a started after the prunes


def test_tombstones_pruned_past_a_lagging_replica_make_it_reload(database_url: str) -> None:
    """Without noticing, b would keep the first two deleted trajectories in its index."""
    with context(database_url) as a, context(database_url) as b:
        model = two_joint(a)
        ids = [store(a, model, [[0.1 * k, 0.0], [1.0, 0.5]]) for k in range(5)]
        assert index_ids(b, model) == set(ids)
        with a.sessions() as session:  # b sleeps while three are deleted and two pruned
            for gone in ids[:3]:
                delete_trajectory(session=session, trajectory_id=gone)
            assert prune_tombstones(session, before=LATER) == 2  # the newest stays
            assert session.scalar(sa.select(sa.func.count()).select_from(TrajectoryTombstone)) == 1
        assert index_ids(b, model) == set(ids[3:]) and b.indexes.reloads == 1
        with a.sessions() as session:
            delete_trajectory(session=session, trajectory_id=ids[3])
        assert index_ids(b, model) == {ids[4]} and b.indexes.reloads == 1  # in step: no reload


def test_pruning_keeps_the_rows_from_the_first_recent_one_on(database_url: str) -> None:
    with context(database_url) as ctx, ctx.sessions() as session:
        old, new = LATER - timedelta(days=3), LATER
        for created in (old, new, old, new):  # a clock behind another's: ids out of time order
            session.add(TrajectoryCommit(first_id=1, last_id=1, created_at=created))
        session.commit()
        assert prune_commit_log(session, before=LATER - timedelta(days=1)) == 1
        assert sorted(session.scalars(sa.select(TrajectoryCommit.id))) == [2, 3, 4]


@pytest.mark.postgres
def test_an_open_import_does_not_hold_up_a_sync_and_arrives_when_committed(
    postgres_url: str,
) -> None:
    with context(postgres_url) as a, context(postgres_url) as b:
        model = two_joint(a)
        index_ids(b, model)
        importing = a.sessions()
        writer = write_import(importing, model, 2000)
        during = store(a, model, [[0.9, 0.9], [1.0, 0.5]])  # committed while the import is open
        assert index_ids(b, model) == {during}
        writer.finish()  # its log rows, still uncommitted
        assert index_ids(b, model) == {during}
        importing.commit()
        importing.close()
        ids = index_ids(b, model)
        assert len(ids) == 2001 and ids == stored_ids(a)
