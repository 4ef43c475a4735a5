"""The 3D view's reads through both clients against the real app: a rejected candidate's event,
its path as link poses, the scenes it was validated in and the model's geometry."""

from __future__ import annotations

import math
from collections.abc import Iterator

import httpx
import pytest

import trajcache_client as tc
from tests.client.conftest import FAST_RETRY, LiveServer, make_app
from tests.robots import TWO_JOINT_URDF
from tests.waiting import wait_until
from trajcache_client import AsyncClient, Client

DETOUR = [[0.0, 0.0], [-1.0, 0.0], [1.0, 0.0]]  # swings the shoulder back through -0.5 first
BLOCKER = {
    "id": "blocker",
    "type": "box",
    "size": [0.04] * 3,
    "pose": {"position": [0.25 * math.sin(-0.5), 0.0, 0.1 + 0.25 * math.cos(-0.5)]},
}


@pytest.fixture
def client(database_url: str) -> Iterator[Client]:
    """A blocking client of the live app without a worker pool."""
    with (
        LiveServer(make_app(database_url, worker_backend="none")) as server,
        Client(server.url, retry=FAST_RETRY) as blocking,
    ):
        yield blocking


def test_a_rejection_is_viewed_where_it_failed(client: Client) -> None:
    model_id = client.register_model(TWO_JOINT_URDF).model_id
    client.put_robot("r1", model_id)
    version = client.put_scene("r1", {"objects": [BLOCKER]})
    stored = client.store_trajectory(model_id, DETOUR)
    assert client.plan("r1", [0.02, 0.0], [0.98, 0.0], {"fallback": False}).status == "miss"
    events: list[tc.PlanEvent] = []

    def recorded() -> bool:  # events are written just after the answer
        events[:] = client.plan_events(robot_id="r1").items
        return bool(events)

    assert wait_until(recorded, timeout_s=30, interval_s=0.05), "the plan left no event"
    [event] = events
    [rejection] = event.rejections
    assert isinstance(rejection, tc.RejectedCandidate)
    assert (rejection.pairs[0].link, rejection.pairs[0].other) == ("upper", "blocker")

    view = client.plan_event_view(event.event_id)
    assert view.failure is not None and view.failure.rejection.sample == rejection.sample
    assert view.scene is not None and view.scene.hash == version.hash
    assert view.frames.count == len(view.frames.poses) == rejection.samples
    stored_view = client.trajectory_view(stored.trajectory_id, scene_hash=version.hash)
    assert stored_view.failure is None and stored_view.key_states == DETOUR
    assert client.get_scene_version("r1", 1).hash == client.get_scene_by_hash(version.hash).hash
    model = client.model_view(model_id)
    assert model.link_names[model.elements[0].link] in ("upper", "fore", "base")
    with pytest.raises(tc.NotFoundError, match="not a mesh"):
        client.model_mesh(model_id, 0)
    with pytest.raises(tc.NotFoundError, match="has no file"):
        client.get_model_file(model_id, "meshes/a.stl")


@pytest.mark.anyio
async def test_the_asyncio_client_reads_the_same(database_url: str) -> None:
    app = make_app(database_url, worker_backend="none")
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with AsyncClient("http://trajcache.test", transport=transport) as client:
            model_id = (await client.register_model(TWO_JOINT_URDF)).model_id
            await client.put_robot("r1", model_id)
            version = await client.put_scene("r1", {"objects": [BLOCKER]})
            stored = await client.store_trajectory(model_id, DETOUR, scene_hash=version.hash)
            view = await client.trajectory_view(stored.trajectory_id)
            assert view.scene is not None and view.scene.version == 1
            assert (await client.model_view(model_id)).model_id == model_id
            assert (await client.get_scene_version("r1", 1)).hash == version.hash
            assert (await client.get_scene_by_hash(version.hash)).robot_id == "r1"
            with pytest.raises(tc.NotFoundError):
                await client.plan_event_view(999)
            with pytest.raises(tc.NotFoundError):
                await client.model_mesh(model_id, 0)
            with pytest.raises(tc.NotFoundError):
                await client.get_model_file(model_id, "a.stl")
