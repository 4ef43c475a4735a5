"""Eviction: at most `cache_max_per_model` trajectories per model; the policy picks the rest.

Policies (what is kept; everything beyond the cap is deleted):
- `lru`: the most recently used; a trajectory never used counts as used when it was stored.
- `least_hit`: the most hit, then the most recently used.

Deletes go through tombstones like any other delete, so every replica's in-memory index drops
the trajectories at its next sync. One model is pruned in one transaction (its deletes and
tombstones commit together). Several replicas may prune at once: on PostgreSQL a
transaction-scoped advisory lock per model makes them take turns, so the second one sees what
the first deleted and finds nothing (or only new excess) to delete; on SQLite the database
allows one writer at a time. A DELETE … RETURNING writes tombstones only for rows it actually
deleted, so a trajectory deleted by someone else in between is skipped, never an error.
"""

from __future__ import annotations

import hashlib
import logging
import threading
from dataclasses import dataclass, field
from typing import Any, Literal

import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db.models import RobotModel, Trajectory, TrajectoryTombstone
from trajcache.services.context import ServiceContext
from trajcache.services.errors import InvalidInputError, NotFoundError
from trajcache.services.maintenance.loop import BackgroundLoop

__all__ = ["POLICIES", "EvictionTimer", "ModelPrune", "PruneReport", "prune"]

_log = logging.getLogger(__name__)
Policy = Literal["lru", "least_hit"]
POLICIES: tuple[Policy, ...] = ("lru", "least_hit")
_CHUNK = 500  # ids per DELETE … WHERE id IN (…)
_process_lock = threading.Lock()  # one prune at a time in this process


@dataclass
class ModelPrune:
    """One model: how many trajectories it had, and those deleted (or to delete) by id."""

    model_id: str
    trajectories: int
    ids: list[int] = field(default_factory=list)


@dataclass
class PruneReport:
    """What a prune deleted, or would delete when `dry_run`."""

    dry_run: bool
    policy: Policy
    cap: int
    models: list[ModelPrune] = field(default_factory=list)

    @property
    def deleted(self) -> int:
        """Trajectories deleted (or to delete) over all models."""
        return sum(len(m.ids) for m in self.models)


def _keep_order(policy: Policy) -> list[sa.UnaryExpression[Any]]:
    """Most worth keeping first."""
    recency = sa.func.coalesce(Trajectory.last_used_at, Trajectory.created_at)
    order: list[sa.UnaryExpression[Any]] = [recency.desc(), Trajectory.id.desc()]
    if policy == "least_hit":
        order.insert(0, Trajectory.hits.desc())
    return order


def _advisory_key(model_id: str) -> int:
    digest = hashlib.sha256(f"trajcache.prune:{model_id}".encode()).digest()
    return int.from_bytes(digest[:8], "big", signed=True)


def _over_cap(session: Session, cap: int) -> list[str]:
    rows = session.scalars(
        sa.select(Trajectory.model_id)
        .group_by(Trajectory.model_id)
        .having(sa.func.count() > cap)
        .order_by(Trajectory.model_id)
    ).all()
    return list(rows)


def _prune_model(
    session: Session, model_id: str, cap: int, policy: Policy, dry_run: bool
) -> ModelPrune:
    if not dry_run and session.get_bind().dialect.name == "postgresql":
        session.execute(sa.select(sa.func.pg_advisory_xact_lock(_advisory_key(model_id))))
    count = session.execute(
        sa.select(sa.func.count()).select_from(Trajectory).where(Trajectory.model_id == model_id)
    ).scalar_one()
    victims = [
        int(i)
        for i in session.scalars(
            sa.select(Trajectory.id)
            .where(Trajectory.model_id == model_id)
            .order_by(*_keep_order(policy))
            .offset(cap)
        )
    ]
    if dry_run:
        session.rollback()
        return ModelPrune(model_id, int(count), sorted(victims))
    deleted: list[int] = []
    for k in range(0, len(victims), _CHUNK):
        chunk = victims[k : k + _CHUNK]
        deleted += session.scalars(
            sa.delete(Trajectory)
            .where(Trajectory.id.in_(chunk))
            .returning(Trajectory.id)
            .execution_options(synchronize_session=False)
        ).all()
    if deleted:
        session.execute(
            sa.insert(TrajectoryTombstone),
            [{"trajectory_id": i, "model_id": model_id} for i in sorted(deleted)],
        )
    session.commit()
    return ModelPrune(model_id, int(count), sorted(deleted))


def prune(
    *,
    session: Session,
    cap: int,
    policy: Policy,
    model_id: str | None = None,
    dry_run: bool = True,
) -> PruneReport:
    """Delete (or list, with `dry_run`) every model's trajectories beyond `cap` by `policy`."""
    if cap < 1:
        raise InvalidInputError(f"cap must be at least 1, got {cap}")
    if policy not in POLICIES:
        raise InvalidInputError(f"policy {policy!r} must be one of {', '.join(POLICIES)}")
    if model_id is not None and session.get(RobotModel, model_id) is None:
        raise NotFoundError(f"robot model {model_id!r} not found")
    report = PruneReport(dry_run=dry_run, policy=policy, cap=cap)
    with _process_lock:
        models = [model_id] if model_id is not None else _over_cap(session, cap)
        session.rollback()
        for m in models:
            try:
                report.models.append(_prune_model(session, m, cap, policy, dry_run))
            except BaseException:
                session.rollback()
                raise
    report.models = [m for m in report.models if m.ids or model_id is not None]
    return report


class EvictionTimer(BackgroundLoop):
    """Prunes every `eviction_interval_s` while `cache_max_per_model` is set (the first prune
    is one interval after the start)."""

    thread_name = "eviction"
    step_name = "eviction"

    def __init__(self, ctx: ServiceContext) -> None:
        super().__init__(ctx)
        self.runs = 0

    def first_pause_s(self) -> float:
        return self.ctx.settings.eviction_interval_s

    def step(self) -> float:
        settings = self.ctx.settings
        with self.ctx.sessions() as session:
            report = prune(
                session=session,
                cap=settings.cache_max_per_model,
                policy=settings.eviction_policy,
                dry_run=False,
            )
        self.runs += 1
        if report.deleted:
            _log.info("evicted %d trajectories beyond the cap", report.deleted)
        return settings.eviction_interval_s

    def failure_pause_s(self) -> float:
        return self.ctx.settings.eviction_interval_s
