"""The v1 API router: every resource's routes, each behind the API-key policy of `api.auth`.

Health checks are mounted outside /v1 and stay open.
"""

from __future__ import annotations

from fastapi import APIRouter, Depends

from trajcache.api.auth import authorize
from trajcache.api.routes import (
    admin,
    cartesian,
    ik,
    models,
    motion_plan,
    plan,
    robots,
    seed_jobs,
    stats,
    trajectories,
    view,
)

api_router = APIRouter(dependencies=[Depends(authorize)])
api_router.include_router(plan.router)  # first: routes are matched in order, plan is the hot one
api_router.include_router(models.router)
api_router.include_router(robots.router)
api_router.include_router(trajectories.router)
api_router.include_router(stats.router)
api_router.include_router(seed_jobs.router)
api_router.include_router(admin.router)
api_router.include_router(motion_plan.router)
api_router.include_router(ik.router)
api_router.include_router(cartesian.router)
api_router.include_router(view.router)
