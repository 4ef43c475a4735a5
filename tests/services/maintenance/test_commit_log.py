"""The commit log of imports and its retention: the importer logs every batch it wrote, and the
maintenance loop prunes log rows and tombstones older than `commit_log_retention_s`."""

from __future__ import annotations

from datetime import timedelta

import sqlalchemy as sa

from tests.services.maintenance.test_bulk_import import many, target_ctx  # noqa: F401 (fixture)
from tests.services.maintenance.test_transfer import run_import
from trajcache.db.models import Trajectory, TrajectoryCommit, TrajectoryTombstone, utcnow
from trajcache.services.context import ServiceContext
from trajcache.services.maintenance.commit_log import PRUNE_EVERY_S, CommitLogPruner


def test_an_import_logs_one_range_per_batch_covering_every_row(
    target_ctx: ServiceContext,  # noqa: F811
) -> None:
    report = run_import(target_ctx, many(25), batch_rows=10)
    assert report.inserted == 25
    with target_ctx.sessions() as session:
        ranges = session.execute(sa.select(TrajectoryCommit.first_id, TrajectoryCommit.last_id))
        logged = sorted(ranges.all())
        ids = set(session.scalars(sa.select(Trajectory.id)))
    assert len(logged) == 3  # batches of 10, 10 and 5
    assert ids == {i for a, b in logged for i in range(a, b + 1)}


def test_the_loop_prunes_rows_older_than_the_retention(
    target_ctx: ServiceContext,  # noqa: F811
) -> None:
    now = utcnow()
    retention = timedelta(seconds=target_ctx.settings.commit_log_retention_s)
    ages = [retention * 2, retention + timedelta(minutes=1), timedelta(minutes=1), timedelta(0)]
    with target_ctx.sessions() as session:
        for age in ages:
            session.add(TrajectoryCommit(first_id=1, last_id=1, created_at=now - age))
            session.add(TrajectoryTombstone(trajectory_id=1, model_id="m", deleted_at=now - age))
        session.commit()
    assert CommitLogPruner(target_ctx).step() == PRUNE_EVERY_S
    with target_ctx.sessions() as session:
        assert sorted(session.scalars(sa.select(TrajectoryCommit.id))) == [3, 4]
        assert sorted(session.scalars(sa.select(TrajectoryTombstone.id))) == [3, 4]
