"""The asyncio client against the real app in process (httpx.ASGITransport; SQLite, PostgreSQL)."""

from __future__ import annotations

import asyncio

import pytest

import trajcache_client as tc
from tests.client.test_live import PATH, TABLE
from tests.robots import TWO_JOINT_URDF
from trajcache_client import AsyncClient

pytestmark = pytest.mark.anyio


async def test_every_endpoint_through_the_async_client(async_client: AsyncClient) -> None:
    client = async_client
    model = await client.register_model(TWO_JOINT_URDF, name="two")
    assert (await client.get_model(model.model_id)).joint_names == ["shoulder", "elbow"]
    assert (await client.list_models()).total == 1
    await client.put_robot("robot-1", model.model_id)
    assert (await client.get_robot("robot-1")).model_id == model.model_id

    version = await client.put_scene("robot-1", {"objects": [TABLE]})
    patched = await client.patch_scene("robot-1", env={"door": 0.3})
    assert patched.version == version.version + 1
    assert (await client.get_scene("robot-1")).env == {"door": 0.3}

    stored = await client.store_trajectory(model.model_id, PATH, robot_id="robot-1")
    assert (await client.list_trajectories(robot_id="robot-1")).total == 1
    # Concurrent plans from one event loop share the client's connection pool.
    answers = await asyncio.gather(
        *(client.plan("robot-1", [0.0, 0.0], [1.0, 0.0], {"fallback": False}) for _ in range(4))
    )
    assert {a.trajectory_id for a in answers} == {stored.trajectory_id}
    assert (await client.get_trajectory(stored.trajectory_id)).states == PATH

    await client.delete_trajectory(stored.trajectory_id)
    with pytest.raises(tc.NotFoundError):
        await client.delete_trajectory(stored.trajectory_id)
    assert (await client.health()).status == "ok" and (await client.ready()).status == "ready"


async def test_async_errors_name_the_problem(async_client: AsyncClient) -> None:
    with pytest.raises(tc.NotFoundError, match="robot model 'nope' not found"):
        await async_client.put_robot("robot-1", "nope")
    with pytest.raises(tc.ValidationError, match="robot id"):
        await async_client.put_robot("bad id!", "nope")
