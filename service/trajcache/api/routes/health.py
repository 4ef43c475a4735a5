"""Liveness (`/healthz`, no database) and readiness (`/readyz`, `SELECT 1`)."""

from __future__ import annotations

from fastapi import APIRouter

from trajcache.api.deps import CtxDep
from trajcache.api.schemas import HealthOut

router = APIRouter(tags=["health"])


@router.get("/healthz", response_model=HealthOut, summary="The process is alive")
def healthz() -> HealthOut:
    """Always ok while the process serves requests; does not touch the database."""
    return HealthOut(status="ok")


@router.get(
    "/readyz",
    response_model=HealthOut,
    summary="The database answers",
    responses={503: {"description": "Database unavailable"}},
)
def readyz(ctx: CtxDep) -> HealthOut:
    """Ready when the database answers `SELECT 1`; 503 otherwise."""
    ctx.ping()
    return HealthOut(status="ready")
