"""A planning worker killed (SIGKILL) while it plans a request that came through the API."""

from __future__ import annotations

import os
import signal
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail, ctx_of
from tests.api.test_fallback import GOAL, START
from tests.faults.held import HELD_TASK, Hold, held_planning
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
from trajcache.jobs.pool import OVERHEAD_S, make_pool

BUDGET_S = 5.0
CELERY_BUDGET_S = 3.0


@pytest.fixture
def local_client(tmp_path: Path) -> Iterator[TestClient]:
    """The app on SQLite; its local pool (2 workers) runs the real planner behind a hold."""
    with app_client(f"sqlite:///{tmp_path / 'faults.db'}", worker_processes=2) as client:
        ctx = ctx_of(client)
        ctx.planner = make_pool(ctx.settings, task_fn=held_planning)
        yield client


@pytest.fixture
def hold(local_client: TestClient) -> Iterator[Hold]:
    """Robot `r1` in a scene of its own, whose planning attempts are held."""
    held = Hold(setup_robot(local_client, unique_scene()))
    held.hold()
    yield held
    held.clear()


def test_killed_worker_is_retried_transparently(local_client: TestClient, hold: Hold) -> None:
    # Two misses plan at once, one per worker; killing one worker breaks the whole process
    # pool, so both requests lose their run: both are retried on the new workers.
    goals = [GOAL, [1.0, 0.3]]
    asked = [ask_in_background(local_client, goal, budget_s=BUDGET_S) for goal in goals]
    victim = hold.wait_attempt(1)
    hold.wait_attempt(2)
    os.kill(victim, signal.SIGKILL)
    hold.wait_attempt(3)  # a retry started on a new worker while the hold is still on
    hold.release()
    for thread, _ in asked:
        thread.join(timeout=BUDGET_S + OVERHEAD_S + 5.0)
    for (_, replies), goal in zip(asked, goals, strict=True):
        assert replies, "the request did not finish"
        reply, took = replies[0]
        assert reply.status_code == 200, reply.text
        body = reply.json()
        assert (body["status"], body["source"]) == ("success", "planner"), reply.text
        assert body["states"][0] == START and body["states"][-1] == goal
        assert took < BUDGET_S + OVERHEAD_S + SLACK_S
    assert victim not in hold.attempts()[2:], "a retry ran on the killed worker"
    pool = ctx_of(local_client).planner
    assert pool is not None
    stats = pool.stats()
    assert (stats.crashes, stats.recycles) == (1, 1), stats
    # Stored: the same requests are now cache hits.
    for goal in goals:
        again = plan(local_client, goal=goal).json()
        assert (again["status"], again["source"]) == ("success", "cache"), again


def test_worker_killed_again_on_the_retry_is_a_clear_503(
    local_client: TestClient, hold: Hold
) -> None:
    thread, replies = ask_in_background(local_client, GOAL, budget_s=BUDGET_S)
    os.kill(hold.wait_attempt(1), signal.SIGKILL)
    os.kill(hold.wait_attempt(2), signal.SIGKILL)  # the retry's worker too
    thread.join(timeout=BUDGET_S + OVERHEAD_S + 5.0)
    assert replies, "the request did not finish"
    reply, took = replies[0]
    assert took < BUDGET_S + OVERHEAD_S + SLACK_S
    assert_detail(reply, 503, "planning is unavailable", "planning worker crashed")
    assert len(hold.attempts()) == 2  # one retry, not more

    hold.release()
    body = plan(local_client, budget_s=BUDGET_S).json()
    assert (body["status"], body["source"]) == ("success", "planner"), body
    assert local_client.get("/v1/stats").status_code == 200  # and everything else still works


@pytest.mark.redis
def test_killed_celery_worker_is_a_clear_503_then_a_new_worker_plans(
    redis_url: str, tmp_path: Path
) -> None:
    queue = f"plan-fault-{uuid.uuid4().hex[:8]}"
    command = worker_command(queue)
    database_url = f"sqlite:///{tmp_path / 'faults.db'}"
    first = Worker(
        command, queue, tmp_path / "first.log", redis_url, HELD_TASK, database_url=database_url
    )
    second: Worker | None = None
    hold: Hold | None = None
    settings = {
        "worker_backend": "celery",
        "celery_queue": queue,
        "celery_broker_url": redis_url,
        "celery_result_backend": redis_url,
    }
    try:
        wait_ready(first)
        with app_client(database_url, **settings) as client:
            hold = Hold(setup_robot(client, unique_scene()))
            hold.hold()
            thread, replies = ask_in_background(client, GOAL, budget_s=CELERY_BUDGET_S)
            hold.wait_attempt(1)
            os.kill(first.process.pid, signal.SIGKILL)  # the worker, while its child plans
            thread.join(timeout=CELERY_BUDGET_S + OVERHEAD_S + 5.0)
            assert replies, "the request did not finish"
            reply, took = replies[0]
            assert took < CELERY_BUDGET_S + OVERHEAD_S + SLACK_S
            assert_detail(reply, 503, "planning is unavailable", "worker", "lost")
            hold.release()

            # No worker at all: a 503 too, once the budget and the overhead have passed.
            reply = plan(client, budget_s=0.5)
            assert_detail(reply, 503, "no Celery worker started", f"within {0.5 + OVERHEAD_S:g} s")

            second = Worker(
                command,
                queue,
                tmp_path / "second.log",
                redis_url,
                HELD_TASK,
                database_url=database_url,
            )
            wait_ready(second)
            body = plan(client, budget_s=CELERY_BUDGET_S).json()  # the same query as the lost one
            assert (body["status"], body["source"]) == ("success", "planner"), body
            assert body["states"][0] == START and body["states"][-1] == GOAL
    finally:
        if hold is not None:
            hold.clear()
        first.stop()
        if second is not None:
            second.stop()
