"""`trajcache worker`: run a Celery planning worker."""

from __future__ import annotations

from typing import Annotated

import typer

from trajcache.cli.warm import warm_kernels


def worker(
    concurrency: Annotated[
        int | None,
        typer.Option(min=1, help="Worker processes (default: TRAJCACHE_WORKER_PROCESSES)."),
    ] = None,
    loglevel: Annotated[str, typer.Option(metavar="LEVEL", help="Celery log level.")] = "info",
    queues: Annotated[
        str | None,
        typer.Option(
            metavar="QUEUES",
            help="Comma-separated queues to consume (default: TRAJCACHE_CELERY_QUEUE).",
        ),
    ] = None,
    hostname: Annotated[
        str | None,
        typer.Option(
            metavar="NAME",
            help="Node name, unique per worker (e.g. 'planner1@%h') (default: celery@%h).",
        ),
    ] = None,
) -> None:
    """Run a Celery worker that plans `trajcache.plan` tasks from the configured broker."""
    from trajcache.core.config import get_settings
    from trajcache.jobs.celery_app import celery_app

    settings = get_settings()
    if concurrency is None:
        concurrency = settings.worker_processes
    if queues is None:
        queues = settings.celery_queue
    argv = [
        "worker",
        f"--concurrency={concurrency}",
        f"--loglevel={loglevel}",
        f"--queues={queues}",
    ]
    if hostname is not None:
        argv.append(f"--hostname={hostname}")
    warm_kernels()  # with its progress; the worker's own warming then finds them ready
    celery_app.worker_main(argv)
