"""/v1/admin: prune the cache to its cap; export and import it as JSON Lines."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from typing import Annotated, Literal

from anyio import from_thread
from fastapi import APIRouter, Query, Request
from fastapi.responses import StreamingResponse
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool

from trajcache.api.bounded import BoundedBodyRoute
from trajcache.api.deps import CtxDep, SessionDep, SettingsDep
from trajcache.api.responses import COMMON, errors
from trajcache.api.schemas.trajectories import SourceName
from trajcache.core.request_model import RequestModel
from trajcache.services.errors import InvalidInputError
from trajcache.services.maintenance.eviction import prune
from trajcache.services.maintenance.importer import import_lines as run_import
from trajcache.services.maintenance.reading import export_lines
from trajcache.services.maintenance.transfer import (
    ExportFilter,
    check_filter,
    dumps,
    export_records,
)

router = APIRouter(prefix="/admin", tags=["admin"], responses=COMMON, route_class=BoundedBodyRoute)

NDJSON = "application/x-ndjson"
_MODEL_ID = "5158592d7f5559c728b6d23f76857a89890f358d7aa40994d9e2338ac93ec821"
_NDJSON_EXAMPLE = (
    '{"type":"header","format":"trajcache-export","version":3,"exported_at":"2025-06-02T09:25:01Z",'
    '"filters":{"model_ids":[],"sources":["sim"],"created_after":null,"created_before":null}}\n'
    '{"type":"model","model_id":"' + _MODEL_ID + '","name":"arm2","base":"fixed",'
    '"joint_names":["j1"],"urdf":"<robot name=\\"arm2\\">…</robot>","files":[],'
    '"acceleration_limits":null,"jerk_limits":null,"end_effector_link":null}\n'
    '{"type":"trajectory","model_id":"' + _MODEL_ID + '","states":[[0.0],[0.3]],"source":"sim",'
    '"robot_id":null,"scene_hash":null,"env":{"stall_2_door":0.52},"content_hash":"9f2c…",'
    '"planning_time_ms":68.2,"created_at":"2025-06-01T10:00:00Z","last_used_at":null,'
    '"last_validated_at":null,"last_real_validated_at":null,"hits":0,"failures":0,'
    '"consecutive_failures":0,"real_validations":0}\n'
    '{"type":"end","trajectories":1,"cartesian_paths":0}\n'
)
MAX_AGE_S = 1e10  # about 300 years: ages beyond cannot be subtracted from today's date


class PruneIn(RequestModel):
    """What to prune; unset fields come from the settings."""

    model_config = ConfigDict(
        json_schema_extra={"examples": [{"dry_run": True, "cap": 5000, "policy": "lru"}]},
    )

    dry_run: bool = Field(default=True, description="Only list what would be deleted.")
    cap: int | None = Field(
        default=None,
        ge=1,
        le=2**63 - 1,  # a 64-bit integer, as the databases store counts
        description="Trajectories kept per model (default: the setting).",
    )
    policy: Literal["lru", "least_hit"] | None = Field(
        default=None, description="What goes first (default: the eviction_policy setting)."
    )
    model_id: str | None = Field(
        default=None, max_length=64, description="Only this model (default: every model)."
    )


class ModelPruneOut(BaseModel):
    """One model's prune: trajectories it had, and the ids deleted (or to delete)."""

    model_id: str
    trajectories: int
    deleted: int
    ids: list[int]


class PruneOut(BaseModel):
    """What was deleted, or would be with `dry_run`."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "dry_run": True,
                    "policy": "lru",
                    "cap": 5000,
                    "deleted": 2,
                    "models": [
                        {"model_id": _MODEL_ID, "trajectories": 5002, "deleted": 2, "ids": [17, 31]}
                    ],
                }
            ]
        }
    )

    dry_run: bool
    policy: Literal["lru", "least_hit"]
    cap: int
    deleted: int
    models: list[ModelPruneOut]


class RejectedLineOut(BaseModel):
    """A line that was not imported, and why."""

    line: int
    reason: str


class ImportOut(BaseModel):
    """What an import did (the first 1000 rejected lines are listed)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "lines": 114,
                    "models_created": 1,
                    "models_existing": 0,
                    "inserted": 111,
                    "duplicates": 1,
                    "cartesian_inserted": 0,
                    "cartesian_duplicates": 0,
                    "rejected_count": 1,
                    "rejected": [
                        {"line": 57, "reason": "state is out of joint limits: joint2 = 2.5 …"}
                    ],
                }
            ]
        }
    )

    lines: int
    models_created: int
    models_existing: int
    inserted: int
    duplicates: int
    cartesian_inserted: int = Field(description="Cartesian paths stored.")
    cartesian_duplicates: int = Field(description="Cartesian paths already there (skipped).")
    rejected_count: int
    rejected: list[RejectedLineOut]


@router.post(
    "/prune",
    response_model=PruneOut,
    summary="Evict trajectories beyond the per-model cap (dry run by default)",
    description="Keeps at most `cap` trajectories per model (default `cache_max_per_model`) and "
    "deletes the rest by the policy: `lru` (least recently used first; never used ones by "
    "creation time) or `least_hit` (fewest hits first). With `dry_run` (the default) nothing "
    "is deleted and the answer lists what would be. Deletes leave tombstones, so every replica "
    "stops serving them at its next sync; concurrent prunes on several replicas are safe.",
    responses=errors(
        {
            404: ("Unknown model", "robot model '5158592d' not found"),
            422: ("No cap", "no cap: pass cap, or set TRAJCACHE_CACHE_MAX_PER_MODEL"),
        }
    ),
)
def prune_route(body: PruneIn, session: SessionDep, settings: SettingsDep) -> PruneOut:
    """Prune (or list what a prune would delete)."""
    cap = body.cap or settings.cache_max_per_model
    if cap < 1:
        raise InvalidInputError("no cap: pass cap, or set TRAJCACHE_CACHE_MAX_PER_MODEL")
    report = prune(
        session=session,
        cap=cap,
        policy=body.policy or settings.eviction_policy,
        model_id=body.model_id,
        dry_run=body.dry_run,
    )
    models = [
        ModelPruneOut(
            model_id=m.model_id, trajectories=m.trajectories, deleted=len(m.ids), ids=m.ids
        )
        for m in report.models
    ]
    return PruneOut(
        dry_run=report.dry_run,
        policy=report.policy,
        cap=report.cap,
        deleted=report.deleted,
        models=models,
    )


@router.get(
    "/export",
    response_class=StreamingResponse,
    summary="Export cached trajectories as JSON Lines (with their models)",
    description="Streams a header line, then per model its line (URDF and files) and its "
    "trajectories, filtered by model, source and age (created within `newer_than_s` seconds, "
    "or more than `older_than_s` ago). The line format is documented with "
    "`trajcache export`; `POST /v1/admin/import` or `trajcache import` read it.",
    responses={
        200: {
            "content": {NDJSON: {"example": _NDJSON_EXAMPLE}},
            "description": "The export, one JSON object per line",
        },
        **errors({404: ("Unknown model", "robot model '5158592d' not found")}),
    },
)
def export_route(
    ctx: CtxDep,
    session: SessionDep,
    model_id: Annotated[list[str] | None, Query(max_length=64)] = None,
    source: Annotated[list[SourceName] | None, Query()] = None,
    newer_than_s: Annotated[float | None, Query(gt=0, le=MAX_AGE_S, allow_inf_nan=False)] = None,
    older_than_s: Annotated[float | None, Query(gt=0, le=MAX_AGE_S, allow_inf_nan=False)] = None,
    models: bool = True,
) -> StreamingResponse:
    """The export, streamed from a session of its own."""
    now = datetime.now(UTC)
    filt = ExportFilter(
        model_ids=tuple(model_id or ()),
        sources=tuple(source or ()),
        created_after=None if newer_than_s is None else now - timedelta(seconds=newer_than_s),
        created_before=None if older_than_s is None else now - timedelta(seconds=older_than_s),
    )
    check_filter(session, filt)  # a 404 before the stream starts

    def lines() -> Iterator[str]:
        with ctx.sessions() as stream_session:
            for record in export_records(session=stream_session, filt=filt, include_models=models):
                yield dumps(record) + "\n"

    return StreamingResponse(lines(), media_type=NDJSON)


@router.post(
    "/import",
    response_model=ImportOut,
    summary="Import an export (JSON Lines, optionally gzip); idempotent",
    description="Reads what `GET /v1/admin/export` or `trajcache export` wrote (gzip "
    "accepted). Models in the file are registered; every trajectory is checked against its "
    "model (state count and length, finite values, joint limits) and stored unless the same "
    "one (same model and states) is already there. Rejected lines are listed with their "
    "reasons; the rest is imported. The import is one transaction: a corrupt, truncated or "
    "empty body (gzip that does not unpack to its end, text that is not UTF-8, a line that is "
    "not JSON, an export of version 2 or later without its end line) is a 422 naming the byte "
    "or line, and nothing is imported. Cartesian paths (version 3) are checked against their "
    "model and proven in the robot's scene before they serve. The body is read as it arrives "
    "and rows are written in batches; "
    "imported trajectories show `quality_pending` until the service has computed their "
    "quality in the background. `source` relabels every trajectory's provenance.",
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {
                NDJSON: {
                    "schema": {"type": "string", "description": "JSON Lines, or gzip of them."},
                    "example": _NDJSON_EXAMPLE,
                }
            },
        }
    },
    responses=errors(
        {
            413: (
                "Body above max_body_bytes",
                "request body has 17000000 bytes, more than max_body_bytes=16777216",
            ),
            422: ("Not an export, or corrupt", "line 12: not JSON: Expecting ',' delimiter …"),
        }
    ),
)
async def import_route(
    request: Request,
    ctx: CtxDep,
    source: Annotated[SourceName | None, Query()] = None,
) -> ImportOut:
    """Import the body as it arrives (never whole in memory), in a worker thread."""
    stream = request.stream()  # bounded while read (BoundedBodyRoute)

    def chunks() -> Iterator[bytes]:
        while True:
            try:
                yield from_thread.run(stream.__anext__)
            except StopAsyncIteration:
                return

    def work() -> ImportOut:
        lines = export_lines(chunks=chunks(), max_bytes=ctx.settings.max_body_bytes)
        with ctx.sessions() as session:
            report = run_import(
                session=session,
                registry=ctx.models,
                settings=ctx.settings,
                lines=lines,
                source=source,
            )
        return ImportOut(
            lines=report.lines,
            models_created=report.models_created,
            models_existing=report.models_existing,
            inserted=report.inserted,
            duplicates=report.duplicates,
            cartesian_inserted=report.cartesian_inserted,
            cartesian_duplicates=report.cartesian_duplicates,
            rejected_count=report.rejected_count,
            rejected=[RejectedLineOut(line=r.line, reason=r.reason) for r in report.rejected],
        )

    return await run_in_threadpool(work)
