"""Seed jobs, statistics, plan events, prune, export and import through both clients against the
real app (SQLite, PostgreSQL); misses end at once (no worker pool), so runs are quick."""

from __future__ import annotations

import gzip
import json
from collections.abc import AsyncIterator, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

import trajcache_client as tc
from tests.client.conftest import FAST_RETRY, LiveServer, make_app
from tests.robots import TWO_JOINT_URDF
from tests.waiting import wait_until
from trajcache_client import AsyncClient, Client

QUICK = {
    "worker_backend": "none",
    "seed_heartbeat_s": 0.1,
    "seed_poll_interval_s": 0.1,
    "seed_lease_s": 3.0,
}
SCENE = {
    "objects": [{"id": "far", "type": "sphere", "size": [0.05], "pose": {"position": [2, 2, 2]}}]
}


def _job(count: int) -> dict[str, Any]:
    queries = [{"start": [0.0, 0.0], "goal": [0.5 + 0.0004 * k, 0.5]} for k in range(count)]
    return {"scenes": [SCENE], "queries": queries}


def _until(read: Any, check: Any, timeout_s: float = 60.0) -> Any:
    seen: list[Any] = [None]

    def reached() -> bool:
        seen[0] = read()
        return bool(check(seen[0]))

    assert wait_until(reached, timeout_s=timeout_s, interval_s=0.02), f"never got there: {seen[0]}"
    return seen[0]


def _body(export: bytes) -> list[bytes]:
    """An export's lines after its header (which says when it was written)."""
    return export.splitlines()[1:]


@pytest.fixture
def quick(database_url: str) -> Iterator[Client]:
    """A blocking client of the live app without a worker pool."""
    with (
        LiveServer(make_app(database_url, **QUICK)) as server,
        Client(server.url, retry=FAST_RETRY) as client,
    ):
        yield client


@pytest.fixture
async def quick_async(database_url: str) -> AsyncIterator[AsyncClient]:
    """An asyncio client of the app in process without a worker pool."""
    app = make_app(database_url, **QUICK)
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with AsyncClient("http://trajcache.test", transport=transport) as client:
            yield client


def test_seed_jobs_are_created_listed_followed_and_cancelled(quick: Client) -> None:
    model_id = quick.register_model(TWO_JOINT_URDF).model_id
    big = quick.create_seed_job({**_job(3000), "name": "big"}, model_id=model_id)
    assert (big.state, big.total, big.name, big.model_id) == ("queued", 3000, "big", model_id)
    cancelled = quick.cancel_seed_job(big.job_id)
    assert cancelled.state == "cancelled" and not cancelled.active
    assert quick.cancel_seed_job(big.job_id).state == "cancelled"  # harmless again

    small = quick.create_seed_job({"model_id": model_id, **_job(2)})
    done = _until(lambda: quick.get_seed_job(small.job_id), lambda j: not j.active)
    assert (done.state, done.done, done.hits + done.planned + done.failed) == ("completed", 2, 2)
    with pytest.raises(tc.ConflictError, match="already completed"):
        quick.cancel_seed_job(small.job_id)

    page = quick.list_seed_jobs()
    assert page.total == 2 and [j.job_id for j in page.items] == [small.job_id, big.job_id]
    assert [j.job_id for j in quick.list_seed_jobs(state="cancelled").items] == [big.job_id]
    assert quick.list_seed_jobs(model_id="nope").total == 0
    with pytest.raises(tc.NotFoundError):
        quick.get_seed_job(999_999)
    with pytest.raises(tc.NotFoundError, match="not found"):
        quick.create_seed_job(_job(1), model_id="nope")


def test_stats_top_trajectories_and_plan_events_follow_the_plans(quick: Client) -> None:
    model_id = quick.register_model(TWO_JOINT_URDF).model_id
    quick.put_robot("robot-1", model_id)
    stored = quick.store_trajectory(model_id, [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]])
    for _ in range(3):
        assert quick.plan("robot-1", [0.0, 0.0], [1.0, 0.0], {"fallback": False}).ok
    quick.plan("robot-1", [0.0, 0.0], [-1.0, 1.0], {"fallback": False})  # a miss

    def totals() -> tc.Metrics:
        return quick.stats(window="1h", group_by="robot").totals

    metrics = _until(totals, lambda m: m.requests == 4)
    assert (metrics.hits, metrics.misses) == (3, 1) and metrics.hit_rate == 0.75
    stats = quick.stats(window="1h", group_by="model", model_id=model_id)
    assert stats.window == "1h" and [g.key for g in stats.groups] == [model_id]
    assert stats.totals.lookup_ms.p50 is not None and stats.series

    (top,) = quick.top_trajectories(limit=5)
    assert (top.trajectory_id, top.hits) == (stored.trajectory_id, 3)
    assert quick.top_trajectories(model_id="nope") == []

    first = quick.plan_events(limit=3, robot_id="robot-1")
    assert len(first.items) == 3 and first.next_cursor is not None
    assert first.items[0].status == "miss"
    rest = quick.plan_events(limit=3, cursor=first.next_cursor)
    assert len(rest.items) == 1 and rest.next_cursor is None
    hits = quick.plan_events(status="success", source="cache", trajectory_id=stored.trajectory_id)
    assert len(hits.items) == 3
    since = first.items[0].created_at
    assert len(quick.plan_events(since=since).items) >= 1
    assert quick.plan_events(until=hits.items[-1].created_at.isoformat()).items == []

    detail = quick.get_trajectory(stored.trajectory_id)
    assert [e.event_id for e in detail.usage_history][:3] == [e.event_id for e in hits.items]
    assert detail.length is not None and "ee_length" in detail.model_fields_set
    with pytest.raises(tc.ValidationError, match="window"):
        quick.stats(window="2w")


def test_prune_export_and_import(quick: Client, tmp_path: Path) -> None:
    model_id = quick.register_model(TWO_JOINT_URDF).model_id
    ids = [
        quick.store_trajectory(model_id, [[0.0, 0.0], [0.01 * (k + 1), 0.5]]).trajectory_id
        for k in range(4)
    ]
    exported = quick.export_cache()
    streamed = b"".join(quick.iter_export_cache(chunk_size=64))
    assert _body(streamed) == _body(exported)
    lines = [json.loads(line) for line in exported.splitlines()]
    assert [line["type"] for line in lines] == ["header", "model"] + ["trajectory"] * 4 + ["end"]
    assert quick.export_cache(sources=["sim"]).count(b"\n") == 2  # header and end
    assert quick.export_cache(model_ids=[model_id], models=False).count(b"\n") == 6
    with pytest.raises(tc.NotFoundError):
        quick.export_cache(model_ids=["nope"])
    with pytest.raises(tc.NotFoundError):
        b"".join(quick.iter_export_cache(model_ids=["nope"]))

    dry = quick.prune(cap=1)
    assert dry.dry_run and dry.deleted == 3 and len(dry.models[0].ids) == 3
    assert quick.list_trajectories().total == 4
    pruned = quick.prune(dry_run=False, cap=1, policy="least_hit", model_id=model_id)
    assert (pruned.dry_run, pruned.deleted, pruned.policy) == (False, 3, "least_hit")
    assert quick.list_trajectories().total == 1 and set(pruned.models[0].ids) < set(ids)

    (tmp_path / "cache.jsonl.gz").write_bytes(gzip.compress(exported))
    imported = quick.import_cache(tmp_path / "cache.jsonl.gz")
    assert (imported.lines, imported.inserted, imported.duplicates) == (7, 3, 1)
    again = quick.import_cache(exported.decode(), source="import")
    assert (again.inserted, again.duplicates, again.rejected_count) == (0, 4, 0)
    *written, end = exported.splitlines(keepends=True)
    unknown = b'{"type": "trajectory", "model_id": "nope"}\n'
    bad = quick.import_cache(b"".join([*written, unknown, end]))
    assert bad.rejected_count == 1 and bad.rejected[0].line == 7


@pytest.mark.anyio
async def test_the_operator_endpoints_through_the_async_client(
    quick_async: AsyncClient,
) -> None:
    client = quick_async
    model_id = (await client.register_model(TWO_JOINT_URDF)).model_id
    stored = await client.store_trajectory(model_id, [[0.0, 0.0], [1.0, 0.0]])
    await client.put_robot("robot-1", model_id)
    assert (await client.plan("robot-1", [0.0, 0.0], [1.0, 0.0], {"fallback": False})).ok

    job = await client.create_seed_job(_job(3000), model_id=model_id)
    assert (await client.cancel_seed_job(job.job_id)).state == "cancelled"
    assert (await client.get_seed_job(job.job_id)).state == "cancelled"
    assert (await client.list_seed_jobs(state="cancelled")).total == 1

    assert (await client.stats(window="1h")).window == "1h"
    assert [t.trajectory_id for t in await client.top_trajectories()] == [stored.trajectory_id]
    events = await client.plan_events(robot_id="robot-1")
    assert events.items and events.items[-1].trajectory_id == stored.trajectory_id

    exported = await client.export_cache()
    chunks = [chunk async for chunk in client.iter_export_cache()]
    assert _body(b"".join(chunks)) == _body(exported)
    assert (await client.prune(cap=1)).deleted == 0
    assert (await client.import_cache(exported)).duplicates == 1
