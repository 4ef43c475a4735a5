"""Services for the paper tables: one running service (one database) per cache, side by side.

The services are started together and measured one after another, so no row shares the
machine with another service's start-up.

Each service is warmed up before it is measured: one planned and one cached request on a robot
of its own, in an empty scene far from the restroom, so that no row pays for starting the
planner's worker or loading code; those trajectories are then deleted, so the cache is empty.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import sqlalchemy as sa

from trajcache.geometry.reference.robot import STOWED_ARM
from trajcache.protocol.replay import RobotClient, cached_count, register_reference_model
from trajcache.protocol.service import free_port

START_DEADLINE_S = 300.0  # services start side by side on a shared machine
WARM_UP_BASE = (-20.0, -20.0, 0.0)  # far outside the restroom
NO_LOOKUP: dict[str, Any] = {"fallback": True, "lookup": False}
# For a service without the `lookup` option: a threshold no two different states fall within.
TINY_THRESHOLD: dict[str, Any] = {"fallback": True, "threshold": 1e-12}


@dataclass
class Cache:
    """One service (one database): its client and the reference model's id."""

    client: httpx.Client
    model_id: str


@contextmanager
def fresh_schema(url: str | None) -> Iterator[str | None]:
    """None (the service's own temporary SQLite file), or a new schema on PostgreSQL `url`."""
    if url is None:
        yield None
        return
    if url.startswith("postgresql://"):
        url = "postgresql+psycopg://" + url.removeprefix("postgresql://")
    schema = f"paper_{uuid.uuid4().hex[:10]}"
    admin = sa.create_engine(url, isolation_level="AUTOCOMMIT")
    with admin.connect() as conn:
        conn.execute(sa.text(f'CREATE SCHEMA "{schema}"'))
    sep = "&" if "?" in url else "?"
    try:
        yield f"{url}{sep}options=-csearch_path%3D{schema}"
    finally:
        with admin.connect() as conn:
            conn.execute(sa.text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()


@contextmanager
def services(urls: list[str | None], deadline_s: float = START_DEADLINE_S) -> Iterator[list[str]]:
    """Start `trajcache serve` per database URL (None: temporary SQLite); yield the base URLs."""
    with ExitStack() as stack:
        procs, bases = [], []
        for url in urls:
            tmp = stack.enter_context(tempfile.TemporaryDirectory())
            port = free_port()
            env = {
                **os.environ,
                "TRAJCACHE_DATABASE_URL": url or f"sqlite:///{Path(tmp) / 'cache.db'}",
                "TRAJCACHE_LOG_LEVEL": "warning",
                "TRAJCACHE_WORKER_PROCESSES": "1",  # one request at a time: one planner process
            }
            cmd = [sys.executable, "-m", "trajcache.cli", "serve", "--host", "127.0.0.1",
                   "--port", str(port), "--workers", "1"]  # fmt: skip
            proc = subprocess.Popen(cmd, env=env, cwd=tmp, stdout=subprocess.DEVNULL)
            stack.callback(_stop, proc)
            procs.append(proc)
            bases.append(f"http://127.0.0.1:{port}")
        waiting = set(range(len(procs)))
        limit = time.monotonic() + deadline_s
        while waiting:
            for i in sorted(waiting):
                if procs[i].poll() is not None:
                    raise RuntimeError(f"the service for {bases[i]} exited while starting")
                with contextlib.suppress(httpx.HTTPError):
                    if httpx.get(f"{bases[i]}/readyz", timeout=2.0).status_code == 200:
                        waiting.discard(i)
            if waiting and time.monotonic() > limit:
                raise RuntimeError(f"{len(waiting)} services not ready after {deadline_s:.0f} s")
            time.sleep(0.3)
        yield bases


def _stop(proc: subprocess.Popen[bytes]) -> None:
    proc.terminate()
    try:
        proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


@contextmanager
def caches(postgres: str | None, names: tuple[str, ...]) -> Iterator[dict[str, Cache]]:
    """One running, warmed-up service per name, each on an empty database of its own."""
    with ExitStack() as stack:
        urls = [stack.enter_context(fresh_schema(postgres)) for _ in names]
        bases = stack.enter_context(services(urls))
        out = {}
        for name, base in zip(names, bases, strict=True):
            client = stack.enter_context(httpx.Client(base_url=base, timeout=120))
            model_id = register_reference_model(client)
            warm_up(client, model_id)
            out[name] = Cache(client, model_id)
        yield out


def warm_up(client: httpx.Client, model_id: str) -> None:
    """Plan once and hit once far from the restroom, then empty the cache again."""
    robot = RobotClient(client, "warm-up", model_id, "sim")
    reply = client.put("/v1/robots/warm-up/scene", json={"objects": [], "env": {}})
    reply.raise_for_status()
    start = [*WARM_UP_BASE, *STOWED_ARM]
    goals = ([start[0], start[1], start[2], start[3] + d, *start[4:]] for d in (0.5, 0.49))
    for goal in goals:
        answer, _ = robot.plan(start, goal, {"fallback": True})
        if answer["status"] != "success":
            raise RuntimeError(f"warm-up plan failed: {answer.get('message')}")
    empty_cache(client, model_id)


def no_cache_options(client: httpx.Client, model_id: str) -> tuple[dict[str, Any], str]:
    """Options that make every call plan, and which kind they are ("lookup off" or threshold)."""
    robot = RobotClient(client, "no-cache-probe", model_id, "sim")
    client.put("/v1/robots/no-cache-probe/scene", json={"objects": [], "env": {}})
    start = [*WARM_UP_BASE, *STOWED_ARM]
    goal = [*start[:3], start[3] + 0.3, *start[4:]]
    try:
        robot.plan(start, goal, NO_LOOKUP)
        chosen, mode = NO_LOOKUP, "lookup off"
    except RuntimeError as exc:
        if "422" not in str(exc) or "lookup" not in str(exc):
            raise
        chosen, mode = TINY_THRESHOLD, "threshold 1e-12"
    empty_cache(client, model_id)
    return chosen, mode


def empty_cache(client: httpx.Client, model_id: str) -> None:
    """Delete every trajectory of `model_id`."""
    while cached_count(client, model_id):
        reply = client.get("/v1/trajectories", params={"model_id": model_id, "limit": 100})
        reply.raise_for_status()
        for item in reply.json()["items"]:
            client.delete(f"/v1/trajectories/{item['trajectory_id']}").raise_for_status()
