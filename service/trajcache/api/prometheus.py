"""`GET /metrics`: the Prometheus exposition of `services.bookkeeping.metrics`, and the planner
pool's sampler running while the app does."""

from __future__ import annotations

import os
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI, Request, Response
from prometheus_client import CONTENT_TYPE_LATEST, multiprocess

from trajcache.core.prometheus_dir import MULTIPROC_ENV
from trajcache.jobs.pool import PlannerPool
from trajcache.services.bookkeeping.metrics import PoolSampler, render

_EXAMPLE = """\
# HELP trajcache_plan_requests_total Plan requests answered, by where the trajectory came from \
(none: no trajectory), status and who asked (robot or seed_job).
# TYPE trajcache_plan_requests_total counter
trajcache_plan_requests_total{requester="robot",source="cache",status="success"} 253.0
trajcache_plan_requests_total{requester="robot",source="planner",status="success"} 19.0
trajcache_plan_requests_total{requester="seed_job",source="planner",status="success"} 140.0
# HELP trajcache_cache_trajectories Trajectories in the cache, by model.
# TYPE trajcache_cache_trajectories gauge
trajcache_cache_trajectories{model="5158592d…"} 1204.0
"""


def install_metrics(app: FastAPI) -> None:
    """Serve `GET /metrics` and sample the planner pool while the app runs."""

    def metrics(request: Request) -> Response:
        sampler: PoolSampler | None = getattr(request.app.state, "pool_sampler", None)
        if sampler is not None:
            sampler.sample()
        return Response(render(request.app.state.ctx.sessions), media_type=CONTENT_TYPE_LATEST)

    app.add_api_route(
        "/metrics",
        metrics,
        methods=["GET"],
        tags=["health"],
        summary="Metrics in the Prometheus text format",
        description="Plan requests by source, status and requester (robots and seed jobs), "
        "lookup/validation/planning latency "
        "histograms, cached trajectories per model, the planner pool's queue depth and worker "
        "failures. With several server processes every answer covers all of them.",
        response_class=Response,
        responses={
            200: {
                "content": {CONTENT_TYPE_LATEST: {"example": _EXAMPLE}},
                "description": "Metrics",
            }
        },
    )
    inner = app.router.lifespan_context

    @asynccontextmanager
    async def lifespan(app_: FastAPI) -> AsyncIterator[Any]:
        async with inner(app_) as state:
            sampler = PoolSampler(lambda: _running_pool(app_))
            app_.state.pool_sampler = sampler
            sampler.start()
            try:
                yield state
            finally:
                sampler.stop()
                if os.environ.get(MULTIPROC_ENV):
                    multiprocess.mark_process_dead(os.getpid())

    app.router.lifespan_context = lifespan


def _running_pool(app: FastAPI) -> PlannerPool | None:
    """The app's planner pool if it has started one (sampling never starts it)."""
    ctx = getattr(app.state, "ctx", None)
    return ctx.planner if ctx is not None else None
