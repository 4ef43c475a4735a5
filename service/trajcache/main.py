"""Builds the FastAPI application (`uvicorn --factory trajcache.main:create_app`)."""

from __future__ import annotations

import os
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from anyio import to_thread
from fastapi import FastAPI
from starlette.concurrency import run_in_threadpool

from trajcache import __version__
from trajcache.api.docs import install_docs
from trajcache.api.errors import UnexpectedErrorMiddleware, install_error_handlers
from trajcache.api.prometheus import install_metrics
from trajcache.api.router import api_router
from trajcache.api.routes import health
from trajcache.core.config import Settings, get_settings
from trajcache.dashboard import mount_dashboard
from trajcache.db import migrate as db_migrate
from trajcache.planning.warm import warm
from trajcache.services.background import start_background
from trajcache.services.context import ServiceContext

AUTO_MIGRATE_ENV = "TRAJCACHE_AUTO_MIGRATE"


def _auto_migrate() -> bool:
    return os.environ.get(AUTO_MIGRATE_ENV, "1").strip().lower() not in {"0", "false", "no"}


def create_app(settings: Settings | None = None, *, migrate: bool | None = None) -> FastAPI:
    """The app; on startup it migrates the database (unless told not to) and opens the engine.

    `migrate=None` reads TRAJCACHE_AUTO_MIGRATE (default on), so `trajcache serve --no-migrate`
    reaches the app factory that uvicorn calls without arguments.
    """
    settings = settings or get_settings()
    run_migrations = _auto_migrate() if migrate is None else migrate

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        if run_migrations:
            await run_in_threadpool(db_migrate.upgrade, settings.database_url)
        # Few request threads (anyio's default is 40): more would only queue for the
        # interpreter lock, and switching between them costs CPU (bench/load.py shows it).
        to_thread.current_default_thread_limiter().total_tokens = settings.request_threads
        await run_in_threadpool(warm)  # no request pays for compiling the kernels
        ctx = ServiceContext.create(settings)
        app.state.ctx = ctx
        if settings.worker_prestart:
            await run_in_threadpool(ctx.planner_pool)
        app.state.background = start_background(ctx)  # seed jobs (resumed) and eviction
        try:
            yield
        finally:
            app.state.background.stop()
            ctx.close()

    app = FastAPI(
        title="trajcache",
        version=__version__,
        summary="A shared, collision-validated trajectory cache for mobile manipulators.",
        lifespan=lifespan,
        docs_url=None,  # install_docs serves them from the package's files
        redoc_url=None,
        redirect_slashes=False,  # a 307 with a body naming the path instead (`api.errors`)
    )
    install_docs(app)
    install_error_handlers(app)
    app.include_router(api_router, prefix="/v1")
    app.include_router(health.router)
    install_metrics(app)
    mount_dashboard(app)
    app.add_middleware(UnexpectedErrorMiddleware)  # outermost but for the server's own
    return app
