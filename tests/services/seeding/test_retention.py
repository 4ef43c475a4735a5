"""Seed jobs' stored scenes are pruned after the retention, never while a trajectory names one."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import sqlalchemy as sa

from tests.services.seeding.conftest import register_two_joint
from trajcache.db.models import SeedJob, SeedJobScene
from trajcache.services.catalog.trajectories import NewTrajectory, store_trajectory
from trajcache.services.context import ServiceContext
from trajcache.services.seeding.retention import prune_seed_scenes
from trajcache.services.seeding.scheduler import SeedScheduler

NOW = datetime(2026, 6, 1, 12, 0, tzinfo=UTC)
WEEK = timedelta(days=7)


def add_job(
    ctx: ServiceContext, model_id: str, *, finished: datetime | None, hashes: list[str]
) -> int:
    """A seed job (finished at `finished`, or still running) with a scene per hash."""
    with ctx.sessions() as session:
        job = SeedJob(
            model_id=model_id,
            state="running" if finished is None else "done",
            spec={},
            total=1,
            finished_at=finished,
            created_at=(finished or NOW) - timedelta(hours=1),
        )
        session.add(job)
        session.flush()
        for k, scene_hash in enumerate(hashes):
            session.add(SeedJobScene(job_id=job.id, position=k, hash=scene_hash, payload={}))
        session.commit()
        return int(job.id)


def scenes(ctx: ServiceContext) -> set[tuple[int, str]]:
    with ctx.sessions() as session:
        return {
            (j, h) for j, h in session.execute(sa.select(SeedJobScene.job_id, SeedJobScene.hash))
        }


def test_old_scenes_go_unless_a_trajectory_names_them(ctx: ServiceContext) -> None:
    model = register_two_joint(ctx)
    with ctx.sessions() as session:
        store_trajectory(
            session=session,
            settings=ctx.settings,
            trajectory=NewTrajectory(
                model=model, states=[[0.0, 0.0], [0.5, 0.5]], source="sim", scene_hash="used"
            ),
        )
    old = add_job(ctx, model.model_id, finished=NOW - 2 * WEEK, hashes=["used", "unused"])
    recent = add_job(ctx, model.model_id, finished=NOW - timedelta(days=1), hashes=["new"])
    running = add_job(ctx, model.model_id, finished=None, hashes=["live"])
    with ctx.sessions() as session:
        assert prune_seed_scenes(session, retention=WEEK, now=NOW) == 1
    kept = {(old, "used"), (recent, "new"), (running, "live")}
    assert scenes(ctx) == kept
    with ctx.sessions() as session:  # nothing more to prune: the rest is used or recent
        assert prune_seed_scenes(session, retention=WEEK, now=NOW) == 0
        session.execute(sa.text("DELETE FROM trajectories"))
        session.commit()
        # once its trajectory is gone, the old scene goes at the next prune
        assert prune_seed_scenes(session, retention=WEEK, now=NOW) == 1
    assert scenes(ctx) == kept - {(old, "used")}


def test_the_scheduler_prunes_with_the_retention_setting(
    ctx: ServiceContext, model_id: str
) -> None:
    now = datetime.now(UTC)
    add_job(ctx, model_id, finished=now - timedelta(days=3), hashes=["a"])
    assert SeedScheduler(ctx).prune_scenes() == 0  # within the default week
    for days, pruned in ((0, 0), (1, 1)):  # 0 days: kept forever
        settings = ctx.settings.model_copy(update={"seed_scene_retention_days": days})
        other = ServiceContext.create(settings)
        try:
            assert SeedScheduler(other).prune_scenes() == pruned
        finally:
            other.close()
    assert scenes(ctx) == set()
