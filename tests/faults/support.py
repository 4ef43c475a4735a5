"""Helpers of the fault tests: the app, a robot in a scene of its own, plans, Celery workers."""

from __future__ import annotations

import sys
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import httpx
from fastapi.testclient import TestClient

from tests.api.conftest import register
from tests.api.test_fallback import DETOUR_SCENE, GOAL, START
from tests.jobs.test_celery import Worker
from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.main import create_app

ROBOT = "r1"
# Request handling around the planner pool's deadline (budget + OVERHEAD_S): HTTP, the plan
# event, the answer. Generous, as on a machine loaded by other jobs, yet well below any budget
# the tests give: waiting for the budget a second time still shows.
SLACK_S = 1.5


@contextmanager
def app_client(database_url: str, **overrides: Any) -> Iterator[TestClient]:
    """The real app (lifespan, migrations) on `database_url`, planner workers started lazily."""
    overrides.setdefault("worker_prestart", False)
    settings = Settings(database_url=database_url, **overrides)
    with TestClient(create_app(settings)) as client:
        yield client


def unique_scene(base: dict[str, Any] | None = None) -> dict[str, Any]:
    """`base` (the detour scene) with an env value of its own: a scene hash no other test has."""
    scene = dict(base or DETOUR_SCENE)
    scene["env"] = {**scene.get("env", {}), "fault_run": uuid.uuid4().int % 10**6 / 10**3}
    return scene


def setup_robot(client: TestClient, scene: dict[str, Any]) -> str:
    """Register the 2-joint model, create robot `r1` in `scene`; return the scene hash."""
    model_id = register(client)["model_id"]
    assert client.put(f"/v1/robots/{ROBOT}", json={"model_id": model_id}).status_code == 201
    reply = client.put(f"/v1/robots/{ROBOT}/scene", json=scene)
    assert reply.status_code == 200, reply.text
    return str(reply.json()["hash"])


def plan(
    client: TestClient, start: list[float] = START, goal: list[float] = GOAL, **options: Any
) -> httpx.Response:
    """POST a plan request for `r1` (the response, whatever its status)."""
    body = {"start": start, "goal": goal, "options": options}
    return client.post(f"/v1/robots/{ROBOT}/plan", json=body)


def worker_command(queue: str) -> list[str]:
    """`trajcache worker` consuming `queue`, one process, named after the queue."""
    cli = "from trajcache.cli import app; app()"
    options = ["--concurrency=1", f"--queues={queue}", f"--hostname={queue}@%h"]
    return [sys.executable, "-c", cli, "worker", *options]


def wait_ready(worker: Worker, timeout: float = 60.0) -> None:
    """Wait until the Celery worker logs that it is ready to take tasks."""
    ready = wait_until(
        lambda: (
            worker.process.poll() is not None or " ready." in worker.log.read_text(errors="replace")
        ),
        timeout_s=timeout,
        interval_s=0.1,
    )
    assert worker.process.poll() is None, f"worker exited:\n{worker.log_tail()}"
    assert ready, f"the Celery worker was not ready within {timeout:g} s"


Replies = list[tuple[httpx.Response, float]]


def ask_in_background(
    client: TestClient, goal: list[float], budget_s: float
) -> tuple[threading.Thread, Replies]:
    """Send a plan request from a thread; its reply and how long it took land in the list."""
    replies: Replies = []

    def ask() -> None:
        began = time.monotonic()
        reply = plan(client, goal=goal, budget_s=budget_s)
        replies.append((reply, time.monotonic() - began))

    thread = threading.Thread(target=ask, daemon=True)
    thread.start()
    return thread, replies
