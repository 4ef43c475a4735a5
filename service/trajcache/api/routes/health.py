"""Liveness (`/healthz`, no database) and readiness (`/readyz`, `SELECT 1`)."""

from __future__ import annotations

from fastapi import APIRouter

from trajcache.api.deps import CtxDep
from trajcache.api.responses import DB_UNAVAILABLE, errors
from trajcache.api.schemas.health import HealthOut

router = APIRouter(tags=["health"])


@router.get(
    "/healthz",
    response_model=HealthOut,
    summary="The process is alive",
    description='Liveness: `{"status": "ok"}` while the process serves requests. It does '
    "not touch the database, so a restart is never triggered by a database outage.",
)
def healthz() -> HealthOut:
    """Always ok while the process serves requests; does not touch the database."""
    return HealthOut(status="ok")


@router.get(
    "/readyz",
    response_model=HealthOut,
    summary="The database answers",
    description='Readiness: `{"status": "ready"}` when the database answers `SELECT 1`, '
    "a 503 otherwise; a load balancer sends traffic only to ready replicas.",
    responses=errors({503: DB_UNAVAILABLE}),
)
def readyz(ctx: CtxDep) -> HealthOut:
    """Ready when the database answers `SELECT 1`; 503 otherwise."""
    ctx.ping()
    return HealthOut(status="ready")
