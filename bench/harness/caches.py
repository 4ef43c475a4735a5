"""Services for the paper tables: one running service (one database) per cache, side by side.

The services are started together and measured one after another, so no row shares the
machine with another service's start-up.

Each service is warmed up before it is measured: one planned and one cached request on a robot
of its own, in an empty scene far from the restroom, so that no row pays for starting the
planner's worker or loading code; those trajectories are then deleted, so the cache is empty.
"""

from __future__ import annotations

import contextlib
import uuid
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from typing import Any

import sqlalchemy as sa

from harness.replay import RobotClient, cached_count, register_reference_model
from harness.service import running_services
from trajcache.reference.robot import STOWED_ARM
from trajcache_client import NO_RETRY, APIError, Client

START_DEADLINE_S = 300.0  # services start side by side on a shared machine
ONE_PLANNER = {"TRAJCACHE_WORKER_PROCESSES": "1"}  # one request at a time: one planner process
WARM_UP_BASE = (-20.0, -20.0, 0.0)  # far outside the restroom
NO_LOOKUP: dict[str, Any] = {"fallback": True, "lookup": False}
# For a service without the `lookup` option: a threshold no two different states fall within.
TINY_THRESHOLD: dict[str, Any] = {"fallback": True, "threshold": 1e-12}


@dataclass
class Cache:
    """One service (one database): its client and the reference model's id."""

    client: Client
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
def caches(postgres: str | None, names: tuple[str, ...]) -> Iterator[dict[str, Cache]]:
    """One running, warmed-up service per name, each on an empty database of its own."""
    with ExitStack() as stack:
        urls = [stack.enter_context(fresh_schema(postgres)) for _ in names]
        bases = stack.enter_context(
            running_services(urls, env=ONE_PLANNER, deadline_s=START_DEADLINE_S, quiet=True)
        )
        out = {}
        for name, base in zip(names, bases, strict=True):
            client = stack.enter_context(Client(base, timeout=120, retry=NO_RETRY))
            model_id = register_reference_model(client)
            warm_up(client, model_id)
            out[name] = Cache(client, model_id)
        yield out


def warm_up(client: Client, model_id: str) -> None:
    """Plan once and hit once far from the restroom, then empty the cache again."""
    robot = RobotClient(client, "warm-up", model_id, "sim")
    client.put_scene("warm-up", {"objects": [], "env": {}})
    start = [*WARM_UP_BASE, *STOWED_ARM]
    goals = ([start[0], start[1], start[2], start[3] + d, *start[4:]] for d in (0.5, 0.49))
    for goal in goals:
        answer, _ = robot.plan(start, goal, {"fallback": True})
        if answer.status != "success":
            raise RuntimeError(f"warm-up plan failed: {answer.message}")
    empty_cache(client, model_id)


def no_cache_options(client: Client, model_id: str) -> tuple[dict[str, Any], str]:
    """Options that make every call plan, and which kind they are ("lookup off" or threshold)."""
    robot = RobotClient(client, "no-cache-probe", model_id, "sim")
    with contextlib.suppress(APIError):  # as before: an error here shows in the probe's plan
        client.put_scene("no-cache-probe", {"objects": [], "env": {}})
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


def empty_cache(client: Client, model_id: str) -> None:
    """Delete every trajectory of `model_id`."""
    while cached_count(client, model_id):
        for item in client.list_trajectories(model_id=model_id, limit=100).items:
            client.delete_trajectory(item.trajectory_id)
