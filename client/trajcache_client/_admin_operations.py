"""The operator's endpoints: seed jobs, statistics, plan events, prune, export and import.

Like `_operations`, one function per endpoint, shared by `Client` and `AsyncClient`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from datetime import datetime
from pathlib import Path
from typing import Any

import httpx
import pydantic

from trajcache_client._admin_models import (
    ImportResult,
    PrunePolicy,
    PruneResult,
    SeedJob,
    SeedJobState,
)
from trajcache_client._exceptions import UnexpectedResponseError
from trajcache_client._models import GoalKind, Page
from trajcache_client._operations import Operation, _query, _reader, _segment
from trajcache_client._stats_models import (
    EventSource,
    EventStatus,
    GroupBy,
    PlanEventPage,
    Requester,
    Stats,
    TopTrajectory,
)

NDJSON = "application/x-ndjson"
_TOP_TRAJECTORIES = pydantic.TypeAdapter(list[TopTrajectory])


def _top_trajectories(response: httpx.Response) -> list[TopTrajectory]:
    try:
        return _TOP_TRAJECTORIES.validate_json(response.content)
    except pydantic.ValidationError as exc:
        raise UnexpectedResponseError(
            f"GET {response.request.url.path} answered a body that is not a list of "
            f"TopTrajectory: {exc}",
            response=response,
        ) from exc


def _body(response: httpx.Response) -> bytes:
    return response.content


def _instant(value: datetime | str | None) -> str | None:
    return value.isoformat() if isinstance(value, datetime) else value


# --- seed jobs ------------------------------------------------------------------------------


def create_seed_job(spec: Mapping[str, Any], *, model_id: str | None = None) -> Operation[SeedJob]:
    """POST /v1/seed-jobs: queue a job (not retried but on 503: each POST queues one)."""
    body = dict(spec)
    if model_id is not None:
        body["model_id"] = model_id
    return Operation("POST", "/v1/seed-jobs", _reader(SeedJob), idempotent=False, json=body)


def list_seed_jobs(
    *,
    state: SeedJobState | None = None,
    model_id: str | None = None,
    limit: int | None = None,
    offset: int = 0,
) -> Operation[Page[SeedJob]]:
    """GET /v1/seed-jobs, newest first, filtered by state and model."""
    params = _query(state=state, model_id=model_id, limit=limit, offset=offset)
    return Operation("GET", "/v1/seed-jobs", _reader(Page[SeedJob]), idempotent=True, params=params)


def get_seed_job(job_id: int) -> Operation[SeedJob]:
    """GET /v1/seed-jobs/{job_id}."""
    path = f"/v1/seed-jobs/{_segment(job_id)}"
    return Operation("GET", path, _reader(SeedJob), idempotent=True)


def cancel_seed_job(job_id: int) -> Operation[SeedJob]:
    """DELETE /v1/seed-jobs/{job_id} (cancelling twice is harmless, so it may be retried)."""
    path = f"/v1/seed-jobs/{_segment(job_id)}"
    return Operation("DELETE", path, _reader(SeedJob), idempotent=True)


# --- statistics and plan events -------------------------------------------------------------


def stats(
    *,
    window: str | None = None,
    group_by: GroupBy | None = None,
    robot_id: str | None = None,
    model_id: str | None = None,
    requester: Requester | None = None,
) -> Operation[Stats]:
    """GET /v1/stats over a window such as "30m", "24h" or "7d" (None: the service's 24h)."""
    params = _query(
        window=window,
        group_by=group_by,
        robot_id=robot_id,
        model_id=model_id,
        requester=requester,
    )
    return Operation("GET", "/v1/stats", _reader(Stats), idempotent=True, params=params)


def top_trajectories(
    *, limit: int | None = None, model_id: str | None = None
) -> Operation[list[TopTrajectory]]:
    """GET /v1/stats/top-trajectories."""
    params = _query(limit=limit, model_id=model_id)
    path = "/v1/stats/top-trajectories"
    return Operation("GET", path, _top_trajectories, idempotent=True, params=params)


def plan_events(
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
    goal_kind: GoalKind | None = None,
) -> Operation[PlanEventPage]:
    """GET /v1/plan-events, newest first; `since` is inclusive, `until` exclusive."""
    params = _query(
        limit=limit,
        cursor=cursor,
        robot_id=robot_id,
        model_id=model_id,
        status=status,
        source=source,
        requester=requester,
        trajectory_id=trajectory_id,
        goal_kind=goal_kind,
        since=_instant(since),
        until=_instant(until),
    )
    return Operation(
        "GET", "/v1/plan-events", _reader(PlanEventPage), idempotent=True, params=params
    )


# --- admin ----------------------------------------------------------------------------------


def prune(
    *,
    dry_run: bool = True,
    cap: int | None = None,
    policy: PrunePolicy | None = None,
    model_id: str | None = None,
) -> Operation[PruneResult]:
    """POST /v1/admin/prune (pruning to a cap twice deletes nothing more: it may be retried)."""
    body = _query(dry_run=dry_run, cap=cap, policy=policy, model_id=model_id)
    return Operation("POST", "/v1/admin/prune", _reader(PruneResult), idempotent=True, json=body)


def export_cache(
    *,
    model_ids: Iterable[str] = (),
    sources: Iterable[str] = (),
    newer_than_s: float | None = None,
    older_than_s: float | None = None,
    models: bool = True,
) -> Operation[bytes]:
    """GET /v1/admin/export: JSON Lines, a header, then each model and its trajectories."""
    params = _query(
        model_id=list(model_ids) or None,
        source=list(sources) or None,
        newer_than_s=newer_than_s,
        older_than_s=older_than_s,
        models=None if models else "false",
    )
    headers = {"accept": NDJSON}
    return Operation(
        "GET", "/v1/admin/export", _body, idempotent=True, params=params, headers=headers
    )


def import_cache(data: bytes | str | Path, *, source: str | None = None) -> Operation[ImportResult]:
    """POST /v1/admin/import: an export's JSON Lines (or their gzip); importing twice adds
    nothing, so it may be retried."""
    if isinstance(data, Path):
        data = data.read_bytes()
    content = data.encode() if isinstance(data, str) else bytes(data)
    return Operation(
        "POST",
        "/v1/admin/import",
        _reader(ImportResult),
        idempotent=True,
        params=_query(source=source),
        content=content,
        headers={"content-type": NDJSON},
    )
