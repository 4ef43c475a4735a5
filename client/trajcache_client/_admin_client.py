"""The operator's methods of `Client` and `AsyncClient`: seed jobs, statistics, plan events,
prune, export and import (each a one-line call of its operation)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from datetime import datetime
from pathlib import Path
from typing import Any, TypeVar

from trajcache_client import _admin_operations as ops
from trajcache_client._admin_models import (
    ImportResult,
    PrunePolicy,
    PruneResult,
    SeedJob,
    SeedJobState,
)
from trajcache_client._models import Page
from trajcache_client._operations import Operation
from trajcache_client._stats_models import (
    EventSource,
    EventStatus,
    GroupBy,
    PlanEventPage,
    Requester,
    Stats,
    TopTrajectory,
)

T = TypeVar("T")


class AdminMethods:
    """Methods of the blocking client over `call`."""

    def call(self, op: Operation[T]) -> T:
        """Send `op` and return its answer (the client's own `call`)."""
        raise NotImplementedError

    # --- seed jobs --------------------------------------------------------------------------

    def create_seed_job(self, spec: Mapping[str, Any], *, model_id: str | None = None) -> SeedJob:
        """Queue a seed job (the `POST /v1/seed-jobs` body); `model_id` fills in its model."""
        return self.call(ops.create_seed_job(spec, model_id=model_id))

    def list_seed_jobs(
        self,
        *,
        state: SeedJobState | None = None,
        model_id: str | None = None,
        limit: int | None = None,
        offset: int = 0,
    ) -> Page[SeedJob]:
        """A page of seed jobs, newest first."""
        return self.call(
            ops.list_seed_jobs(state=state, model_id=model_id, limit=limit, offset=offset)
        )

    def get_seed_job(self, job_id: int) -> SeedJob:
        """A seed job's state and progress."""
        return self.call(ops.get_seed_job(job_id))

    def cancel_seed_job(self, job_id: int) -> SeedJob:
        """Cancel a queued or running seed job (ConflictError when it already ended)."""
        return self.call(ops.cancel_seed_job(job_id))

    # --- statistics and plan events ---------------------------------------------------------

    def stats(
        self,
        *,
        window: str | None = None,
        group_by: GroupBy | None = None,
        robot_id: str | None = None,
        model_id: str | None = None,
        requester: Requester | None = None,
    ) -> Stats:
        """Hit rate, planner calls, time per step and time saved over a window ("24h"), of
        robots' and seed jobs' requests (`requester`: only theirs)."""
        return self.call(
            ops.stats(
                window=window,
                group_by=group_by,
                robot_id=robot_id,
                model_id=model_id,
                requester=requester,
            )
        )

    def top_trajectories(
        self, *, limit: int | None = None, model_id: str | None = None
    ) -> list[TopTrajectory]:
        """The most reused trajectories, by hits."""
        return self.call(ops.top_trajectories(limit=limit, model_id=model_id))

    def plan_events(
        self,
        *,
        limit: int | None = None,
        cursor: str | None = None,
        robot_id: str | None = None,
        model_id: str | None = None,
        status: EventStatus | None = None,
        source: EventSource | None = None,
        requester: Requester | None = None,
        trajectory_id: int | None = None,
        since: datetime | str | None = None,
        until: datetime | str | None = None,
    ) -> PlanEventPage:
        """A page of plan events, newest first; pass `next_cursor` as `cursor` to go on."""
        return self.call(
            ops.plan_events(
                limit=limit,
                cursor=cursor,
                robot_id=robot_id,
                model_id=model_id,
                status=status,
                source=source,
                requester=requester,
                trajectory_id=trajectory_id,
                since=since,
                until=until,
            )
        )

    # --- admin ------------------------------------------------------------------------------

    def prune(
        self,
        *,
        dry_run: bool = True,
        cap: int | None = None,
        policy: PrunePolicy | None = None,
        model_id: str | None = None,
    ) -> PruneResult:
        """Evict trajectories beyond the per-model cap (with `dry_run`, only list them)."""
        return self.call(ops.prune(dry_run=dry_run, cap=cap, policy=policy, model_id=model_id))

    def export_cache(
        self,
        *,
        model_ids: Iterable[str] = (),
        sources: Iterable[str] = (),
        newer_than_s: float | None = None,
        older_than_s: float | None = None,
        models: bool = True,
    ) -> bytes:
        """The cache as JSON Lines, whole (`iter_export_cache` streams it)."""
        return self.call(
            ops.export_cache(
                model_ids=model_ids,
                sources=sources,
                newer_than_s=newer_than_s,
                older_than_s=older_than_s,
                models=models,
            )
        )

    def import_cache(self, data: bytes | str | Path, *, source: str | None = None) -> ImportResult:
        """Import an export (JSON Lines or their gzip; a Path is read); `source` relabels."""
        return self.call(ops.import_cache(data, source=source))


class AsyncAdminMethods:
    """Methods of the asyncio client over `call`."""

    async def call(self, op: Operation[T]) -> T:
        """Send `op` and return its answer (the client's own `call`)."""
        raise NotImplementedError

    # --- seed jobs --------------------------------------------------------------------------

    async def create_seed_job(
        self, spec: Mapping[str, Any], *, model_id: str | None = None
    ) -> SeedJob:
        """Queue a seed job (the `POST /v1/seed-jobs` body); `model_id` fills in its model."""
        return await self.call(ops.create_seed_job(spec, model_id=model_id))

    async def list_seed_jobs(
        self,
        *,
        state: SeedJobState | None = None,
        model_id: str | None = None,
        limit: int | None = None,
        offset: int = 0,
    ) -> Page[SeedJob]:
        """A page of seed jobs, newest first."""
        return await self.call(
            ops.list_seed_jobs(state=state, model_id=model_id, limit=limit, offset=offset)
        )

    async def get_seed_job(self, job_id: int) -> SeedJob:
        """A seed job's state and progress."""
        return await self.call(ops.get_seed_job(job_id))

    async def cancel_seed_job(self, job_id: int) -> SeedJob:
        """Cancel a queued or running seed job (ConflictError when it already ended)."""
        return await self.call(ops.cancel_seed_job(job_id))

    # --- statistics and plan events ---------------------------------------------------------

    async def stats(
        self,
        *,
        window: str | None = None,
        group_by: GroupBy | None = None,
        robot_id: str | None = None,
        model_id: str | None = None,
        requester: Requester | None = None,
    ) -> Stats:
        """Hit rate, planner calls, time per step and time saved over a window ("24h"), of
        robots' and seed jobs' requests (`requester`: only theirs)."""
        return await self.call(
            ops.stats(
                window=window,
                group_by=group_by,
                robot_id=robot_id,
                model_id=model_id,
                requester=requester,
            )
        )

    async def top_trajectories(
        self, *, limit: int | None = None, model_id: str | None = None
    ) -> list[TopTrajectory]:
        """The most reused trajectories, by hits."""
        return await self.call(ops.top_trajectories(limit=limit, model_id=model_id))

    async def plan_events(
        self,
        *,
        limit: int | None = None,
        cursor: str | None = None,
        robot_id: str | None = None,
        model_id: str | None = None,
        status: EventStatus | None = None,
        source: EventSource | None = None,
        requester: Requester | None = None,
        trajectory_id: int | None = None,
        since: datetime | str | None = None,
        until: datetime | str | None = None,
    ) -> PlanEventPage:
        """A page of plan events, newest first; pass `next_cursor` as `cursor` to go on."""
        return await self.call(
            ops.plan_events(
                limit=limit,
                cursor=cursor,
                robot_id=robot_id,
                model_id=model_id,
                status=status,
                source=source,
                requester=requester,
                trajectory_id=trajectory_id,
                since=since,
                until=until,
            )
        )

    # --- admin ------------------------------------------------------------------------------

    async def prune(
        self,
        *,
        dry_run: bool = True,
        cap: int | None = None,
        policy: PrunePolicy | None = None,
        model_id: str | None = None,
    ) -> PruneResult:
        """Evict trajectories beyond the per-model cap (with `dry_run`, only list them)."""
        return await self.call(
            ops.prune(dry_run=dry_run, cap=cap, policy=policy, model_id=model_id)
        )

    async def export_cache(
        self,
        *,
        model_ids: Iterable[str] = (),
        sources: Iterable[str] = (),
        newer_than_s: float | None = None,
        older_than_s: float | None = None,
        models: bool = True,
    ) -> bytes:
        """The cache as JSON Lines, whole (`iter_export_cache` streams it)."""
        return await self.call(
            ops.export_cache(
                model_ids=model_ids,
                sources=sources,
                newer_than_s=newer_than_s,
                older_than_s=older_than_s,
                models=models,
            )
        )

    async def import_cache(
        self, data: bytes | str | Path, *, source: str | None = None
    ) -> ImportResult:
        """Import an export (JSON Lines or their gzip; a Path is read); `source` relabels."""
        return await self.call(ops.import_cache(data, source=source))
