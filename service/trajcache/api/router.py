"""The v1 API router: every resource's routes (health checks are mounted outside /v1)."""

from __future__ import annotations

from fastapi import APIRouter

from trajcache.api.routes import models, plan, robots, trajectories

api_router = APIRouter()
api_router.include_router(models.router)
api_router.include_router(robots.router)
api_router.include_router(plan.router)
api_router.include_router(trajectories.router)
