"""Eviction: the per-model cap, LRU and least-hit policies, tombstones, several replicas."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
import sqlalchemy as sa

from tests.robots import TWO_JOINT_URDF
from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.db import migrate
from trajcache.db.models import Trajectory, TrajectoryTombstone
from trajcache.geometry.model.robot import BaseType
from trajcache.services.background import start_background
from trajcache.services.catalog.models import ModelRegistration, get_model, register_model
from trajcache.services.catalog.trajectories import NewTrajectory, store_trajectory
from trajcache.services.context import ServiceContext
from trajcache.services.errors import InvalidInputError, NotFoundError
from trajcache.services.maintenance.eviction import PruneReport, prune

T0 = datetime(2026, 1, 1, tzinfo=UTC)


@pytest.fixture
def ctx(migrated_url: str) -> Iterator[ServiceContext]:
    context = ServiceContext.create(Settings(database_url=migrated_url, worker_backend="none"))
    yield context
    context.close()


def add(ctx: ServiceContext, model_id: str, k: int, **values: Any) -> int:
    """Trajectory k of the model, with the given usage columns."""
    with ctx.sessions() as session:
        model = get_model(session=session, registry=ctx.models, model_id=model_id)
        new_id, _ = store_trajectory(
            session=session,
            settings=Settings(),
            trajectory=NewTrajectory(
                model=model, states=[[0.0] * model.dof, [0.01 * (k + 1)] * model.dof], source="sim"
            ),
        )
        session.execute(sa.update(Trajectory).where(Trajectory.id == new_id).values(**values))
        session.commit()
    return new_id


@pytest.fixture
def models(ctx: ServiceContext) -> tuple[str, str]:
    with ctx.sessions() as session:
        arm, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(urdf=TWO_JOINT_URDF),
        )
        mobile, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(urdf=TWO_JOINT_URDF, base=BaseType.PLANAR),
        )
    return arm.model_id, mobile.model_id


@pytest.fixture
def usage(ctx: ServiceContext, models: tuple[str, str]) -> dict[str, int]:
    """Six trajectories of the arm with distinct recency and hits, two of the mobile model."""
    arm, mobile = models
    day = timedelta(days=1)
    ids = {
        "old_unused": add(ctx, arm, 0, created_at=T0, hits=0),
        "old_used_recently": add(ctx, arm, 1, created_at=T0, last_used_at=T0 + 9 * day, hits=1),
        "mid_many_hits": add(ctx, arm, 2, created_at=T0 + day, last_used_at=T0 + 2 * day, hits=50),
        "new_unused": add(ctx, arm, 3, created_at=T0 + 8 * day, hits=0),
        "used_day_3": add(ctx, arm, 4, created_at=T0, last_used_at=T0 + 3 * day, hits=5),
        "used_day_7": add(ctx, arm, 5, created_at=T0, last_used_at=T0 + 7 * day, hits=2),
    }
    ids["mobile_a"] = add(ctx, mobile, 0, created_at=T0)
    ids["mobile_b"] = add(ctx, mobile, 1, created_at=T0)
    return ids


def names(report: PruneReport, ids: dict[str, int]) -> set[str]:
    by_id = {v: k for k, v in ids.items()}
    return {by_id[i] for m in report.models for i in m.ids}


def remaining(ctx: ServiceContext) -> set[int]:
    with ctx.sessions() as session:
        return set(session.scalars(sa.select(Trajectory.id)))


def tombstones(ctx: ServiceContext) -> list[int]:
    with ctx.sessions() as session:
        return sorted(session.scalars(sa.select(TrajectoryTombstone.trajectory_id)))


def test_lru_deletes_the_least_recently_used(ctx: ServiceContext, usage: dict[str, int]) -> None:
    with ctx.sessions() as session:
        report = prune(session=session, cap=3, policy="lru", dry_run=False)
    # recency = last use, or creation for a never-used one: day 0, 2, 3 go; 7, 8, 9 stay
    assert names(report, usage) == {"old_unused", "mid_many_hits", "used_day_3"}
    assert [m.trajectories for m in report.models] == [6]  # the mobile model is under the cap
    assert remaining(ctx) == set(usage.values()) - {
        usage[n] for n in ("old_unused", "mid_many_hits", "used_day_3")
    }


def test_least_hit_deletes_the_fewest_hits(ctx: ServiceContext, usage: dict[str, int]) -> None:
    with ctx.sessions() as session:
        report = prune(session=session, cap=3, policy="least_hit", dry_run=False)
    # hits 0, 0, 1 go (the two unused ones by recency: both lose to hits ≥ 1 anyway)
    assert names(report, usage) == {"old_unused", "new_unused", "old_used_recently"}


def test_least_hit_breaks_ties_by_recency(ctx: ServiceContext, usage: dict[str, int]) -> None:
    with ctx.sessions() as session:
        report = prune(session=session, cap=4, policy="least_hit", dry_run=True)
    assert names(report, usage) == {"old_unused", "new_unused"}
    with ctx.sessions() as session:
        report = prune(session=session, cap=5, policy="least_hit", dry_run=True)
    assert names(report, usage) == {"old_unused"}  # the older of the two never-hit ones


def test_dry_run_deletes_nothing(ctx: ServiceContext, usage: dict[str, int]) -> None:
    with ctx.sessions() as session:
        report = prune(session=session, cap=1, policy="lru", dry_run=True)
    assert report.dry_run and report.deleted == 5 + 1
    assert remaining(ctx) == set(usage.values())
    assert tombstones(ctx) == []


def test_deletes_leave_tombstones_once_and_replicas_drop_them(
    ctx: ServiceContext, migrated_url: str, usage: dict[str, int], models: tuple[str, str]
) -> None:
    other = ServiceContext.create(Settings(database_url=migrated_url, worker_backend="none"))
    try:
        with other.sessions() as session:
            model = get_model(session=session, registry=other.models, model_id=models[0])
            assert len(other.indexes.index(session, model)) == 6
        with ctx.sessions() as session:
            report = prune(session=session, cap=2, policy="lru", dry_run=False)
        deleted = sorted(i for m in report.models for i in m.ids)
        assert len(deleted) == 4 + 0 and tombstones(ctx) == deleted
        with ctx.sessions() as session:
            again = prune(session=session, cap=2, policy="lru", dry_run=False)
        assert again.deleted == 0 and tombstones(ctx) == deleted  # idempotent
        with other.sessions() as session:
            index = other.indexes.index(session, model)
            assert len(index) == 2
            assert not any(i in index for i in deleted)
    finally:
        other.close()


def test_one_model_and_bad_input(
    ctx: ServiceContext, usage: dict[str, int], models: tuple[str, str]
) -> None:
    arm, mobile = models
    with ctx.sessions() as session:
        report = prune(session=session, cap=1, policy="lru", model_id=mobile, dry_run=False)
        assert [m.model_id for m in report.models] == [mobile]
        assert names(report, usage) == {"mobile_a"}  # same creation time: the lower id goes
        under = prune(session=session, cap=10, policy="lru", model_id=arm, dry_run=True)
        assert [(m.model_id, m.trajectories, m.ids) for m in under.models] == [(arm, 6, [])]
        with pytest.raises(NotFoundError):
            prune(session=session, cap=1, policy="lru", model_id="nope")
        with pytest.raises(InvalidInputError, match="cap"):
            prune(session=session, cap=0, policy="lru")
        with pytest.raises(InvalidInputError, match="policy"):
            prune(session=session, cap=1, policy="oldest")  # type: ignore[arg-type]


@pytest.mark.postgres
def test_replicas_pruning_at_once(postgres_url: str) -> None:
    migrate.upgrade(postgres_url)
    replicas = [
        ServiceContext.create(Settings(database_url=postgres_url, worker_backend="none"))
        for _ in range(4)
    ]
    try:
        with replicas[0].sessions() as session:
            arm, _ = register_model(
                session=session,
                registry=replicas[0].models,
                registration=ModelRegistration(urdf=TWO_JOINT_URDF),
            )
        ids = [
            add(replicas[0], arm.model_id, k, created_at=T0 + timedelta(minutes=k))
            for k in range(40)
        ]
        barrier = threading.Barrier(len(replicas))
        reports: list[PruneReport] = []
        errors: list[BaseException] = []

        def run(ctx: ServiceContext) -> None:
            try:
                with ctx.sessions() as session:
                    barrier.wait()
                    reports.append(prune(session=session, cap=10, policy="lru", dry_run=False))
            except BaseException as exc:
                errors.append(exc)

        threads = [threading.Thread(target=run, args=(c,)) for c in replicas]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert errors == []
        assert sum(r.deleted for r in reports) == 30
        assert remaining(replicas[0]) == set(ids[30:])  # the 10 newest
        assert tombstones(replicas[0]) == sorted(ids[:30])
    finally:
        for c in replicas:
            c.close()


def test_timed_eviction_keeps_the_cap(migrated_url: str) -> None:
    ctx = ServiceContext.create(
        Settings(
            database_url=migrated_url,
            worker_backend="none",
            cache_max_per_model=2,
            eviction_interval_s=0.05,
        )
    )
    background = start_background(ctx)
    try:
        assert background.eviction is not None
        with ctx.sessions() as session:
            arm, _ = register_model(
                session=session,
                registry=ctx.models,
                registration=ModelRegistration(urdf=TWO_JOINT_URDF),
            )
        ids = [add(ctx, arm.model_id, k, created_at=T0 + timedelta(minutes=k)) for k in range(5)]
        assert wait_until(lambda: remaining(ctx) == set(ids[3:]), timeout_s=10)
    finally:
        background.stop()
        ctx.close()
    off = ServiceContext.create(Settings(database_url=migrated_url, worker_backend="none"))
    try:
        quiet = start_background(off)
        assert quiet.eviction is None  # no cap, no timer
        quiet.stop()
    finally:
        off.close()
