"""Redis goes away in Celery mode, for the app only: misses are 503s, hits are still served."""

from __future__ import annotations

import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail, ctx_of
from tests.api.test_fallback import GOAL, START
from tests.faults.held import HELD_TASK, Hold
from tests.faults.support import (
    SLACK_S,
    app_client,
    ask_in_background,
    plan,
    setup_robot,
    unique_scene,
    wait_ready,
    worker_command,
)
from tests.jobs.test_celery import Worker
from tests.proxy import TcpProxy
from tests.waiting import wait_until
from trajcache.jobs.pool import OVERHEAD_S

pytestmark = pytest.mark.redis

BUDGET_S = 3.0


@pytest.fixture
def worker(redis_url: str, tmp_path: Path) -> Iterator[Worker]:
    """`trajcache worker` on a queue of its own, connected to Redis directly."""
    queue = f"plan-fault-{uuid.uuid4().hex[:8]}"
    log = tmp_path / "worker.log"
    database_url = f"sqlite:///{tmp_path / 'faults.db'}"  # the app's, below
    started = Worker(
        worker_command(queue), queue, log, redis_url, HELD_TASK, database_url=database_url
    )
    try:
        wait_ready(started)
        yield started
    finally:
        started.stop()


def test_redis_outage_is_a_quick_503_for_misses_hits_still_served(
    redis_url: str, worker: Worker, tmp_path: Path
) -> None:
    proxy = TcpProxy(("127.0.0.1", 6379))
    proxy.start()
    proxied = redis_url.replace("127.0.0.1:6379", f"127.0.0.1:{proxy.port}")
    assert proxied != redis_url
    settings = {
        "worker_backend": "celery",
        "celery_queue": worker.queue,
        "celery_broker_url": proxied,
        "celery_result_backend": proxied,
    }
    try:
        with app_client(f"sqlite:///{tmp_path / 'faults.db'}", **settings) as client:
            hold = Hold(setup_robot(client, unique_scene()))
            try:
                _outage_cycle(client, proxy, hold)
            finally:
                hold.clear()
    finally:
        proxy.stop()


def _planned(client: TestClient, goal: list[float]) -> dict[str, object]:
    body = plan(client, goal=goal, budget_s=BUDGET_S).json()
    assert (body["status"], body["source"]) == ("success", "planner"), body
    return dict(body)


def _outage_cycle(client: TestClient, proxy: TcpProxy, hold: Hold) -> None:
    cached = _planned(client, GOAL)  # through Redis and the worker; stored

    # A miss in flight when Redis goes away: its result cannot come back.
    hold.hold()
    thread, replies = ask_in_background(client, [1.0, 0.3], budget_s=BUDGET_S)
    hold.wait_attempt(1)
    proxy.stop()
    hold.release()  # the worker finishes; its result stays in Redis, out of the app's reach
    thread.join(timeout=BUDGET_S + OVERHEAD_S + 5.0)
    assert replies, "the request did not finish"
    reply, took = replies[0]
    assert took < BUDGET_S + OVERHEAD_S + SLACK_S
    assert_detail(reply, 503, "planning is unavailable", "worker backend unavailable")

    pool = ctx_of(client).planner_pool()
    for goal in ([1.0, 0.5], [1.0, 0.3]):  # new misses: a 503 at once, not at the deadline
        began = time.monotonic()
        reply = plan(client, goal=goal, budget_s=BUDGET_S)
        # Fail fast is the promise: a broker out of reach is not waited on for the budget.
        assert time.monotonic() - began < BUDGET_S
        assert_detail(reply, 503, "planning is unavailable", "worker backend unavailable")

        submitted = pool.stats().submitted  # a hit needs no Redis: the pool is not asked
        body = plan(client, budget_s=BUDGET_S).json()
        assert pool.stats().submitted == submitted
        assert (body["source"], body["trajectory_id"]) == ("cache", cached["trajectory_id"])
        assert body["states"][0] == START

    proxy.start()  # Redis is back: misses are planned again, by the same app
    replies: list[Any] = []
    recovered = wait_until(
        lambda: (
            replies.append(plan(client, goal=[1.0, 0.3], budget_s=BUDGET_S))
            or replies[-1].status_code != 503
        ),
        timeout_s=10.0,
        interval_s=0.2,
    )
    assert recovered, f"no recovery: {replies[-1].text}"
    body = replies[-1].json()
    assert (body["status"], body["source"]) == ("success", "planner"), body
    _planned(client, [1.0, 0.5])
