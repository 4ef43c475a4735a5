"""`trajcache serve` and `trajcache migrate`: run the HTTP service, upgrade its database."""

from __future__ import annotations

import errno
import os
import signal
import socket
import sys
import threading
import time
import urllib.request
from types import FrameType
from typing import Annotated

import typer
from rich.console import Console

from trajcache.cli.common import (
    DatabaseUrlOption,
    err_console,
    fail,
    load_settings,
    require_database,
    upgrade_database,
)
from trajcache.cli.warm import warm_kernels


def check_port(host: str, port: int) -> None:
    """Exit 2 with one line unless `host:port` can be bound now, as uvicorn will bind it."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, port))
        except OSError as exc:
            shown = f"[{host}]" if ":" in host else host
            reason = exc.strerror or str(exc)
            if exc.errno == errno.EADDRINUSE:
                reason += " (another service listens there; choose --port or TRAJCACHE_PORT)"
            raise fail(RuntimeError(f"cannot serve on {shown}:{port}: {reason}")) from None


def _probe_url(host: str, port: int) -> str:
    """Where this machine reaches a service bound to `host` (a wildcard: loopback)."""
    if host in ("0.0.0.0", ""):
        host = "127.0.0.1"
    elif host == "::":
        host = "::1"
    return f"http://[{host}]:{port}" if ":" in host else f"http://{host}:{port}"


_DIRECT = urllib.request.build_opener(urllib.request.ProxyHandler({}))  # never through a proxy


def _answers(base: str) -> bool:
    try:
        with _DIRECT.open(f"{base}/healthz", timeout=1.0) as response:
            return bool(response.status == 200)
    except (OSError, ValueError):
        return False


def announce_when_answering(base: str, message: str, interval_s: float = 0.2) -> threading.Thread:
    """Print `message` once the service at `base` answers `GET /healthz`, from a daemon thread
    that asks every `interval_s` (so the line follows the app's startup, never precedes it)."""

    def wait_then_print() -> None:
        while not _answers(base):
            time.sleep(interval_s)
        err_console().print(message, soft_wrap=True)

    thread = threading.Thread(target=wait_then_print, name="announce", daemon=True)
    thread.start()
    return thread


def _stop_on_sigterm(_signum: int, _frame: FrameType | None) -> None:
    sys.exit(0)


def serve(
    host: Annotated[
        str | None, typer.Option(metavar="HOST", help="Address to bind (default: TRAJCACHE_HOST).")
    ] = None,
    port: Annotated[
        int | None, typer.Option(min=1, max=65535, help="Port (default: TRAJCACHE_PORT).")
    ] = None,
    workers: Annotated[int, typer.Option(min=1, help="Server worker processes.")] = 1,
    no_migrate: Annotated[
        bool, typer.Option("--no-migrate", help="Do not upgrade the database on start.")
    ] = False,
    database_url: DatabaseUrlOption = None,
) -> None:
    """Run the HTTP service (settings from TRAJCACHE_* environment variables)."""
    import uvicorn

    from trajcache.core.prometheus_dir import prepare_multiprocess_dir

    settings = load_settings(database_url)
    host = host or settings.host
    port = port or settings.port
    check_port(host, port)  # before anything is said or done: a busy port is one line
    prepare_multiprocess_dir(workers)  # before any metric exists: workers merge /metrics there
    from trajcache.main import AUTO_MIGRATE_ENV

    if no_migrate:
        require_database(settings.database_url)
    else:
        upgrade_database(settings.database_url)  # once here rather than once per worker
    os.environ[AUTO_MIGRATE_ENV] = "0"
    if database_url is not None:
        os.environ["TRAJCACHE_DATABASE_URL"] = settings.database_url  # the app's workers read it
    os.environ["TRAJCACHE_HOST"] = host  # the app decides from it whether keys are required
    shown = f"[{host}]" if ":" in host else host
    # SIGTERM is how a service is asked to stop (Docker, systemd, Kubernetes). uvicorn shuts down
    # gracefully, then raises the signal again for the handler it found: this one ends the
    # process with status 0, through the interpreter's exit handlers (multiprocessing's release
    # the planner pool's semaphores), instead of the default handler killing it.
    signal.signal(signal.SIGTERM, _stop_on_sigterm)
    warm_kernels()  # with its progress; the app's own warming then finds them ready
    message = (
        f"trajcache serving on [bold]http://{shown}:{port}[/bold] "
        f"(API docs at /docs, {workers} worker{'s' if workers > 1 else ''})"
    )
    announce_when_answering(_probe_url(host, port), message)
    uvicorn.run(
        "trajcache.main:create_app",
        factory=True,
        host=host,
        port=port,
        workers=workers,
        log_level=settings.log_level,
    )


def migrate_command(
    revision: Annotated[str, typer.Option(metavar="REVISION", help="Target revision.")] = "head",
    database_url: DatabaseUrlOption = None,
) -> None:
    """Upgrade the database (default: TRAJCACHE_DATABASE_URL) to a revision."""
    from trajcache.db import migrate
    from trajcache.db.session import shown_url

    url = load_settings(database_url).database_url
    upgrade_database(url, revision)
    Console().print(
        f"{shown_url(url)} is at revision [bold]{migrate.current_revision(url)}[/bold]",
        soft_wrap=True,
    )
