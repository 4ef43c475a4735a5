"""Two service replicas on one database: each one's index follows the other's writes."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from tests.robots import TWO_JOINT_URDF
from trajcache.cache.index import TrajectoryIndex
from trajcache.core.config import Settings
from trajcache.main import create_app
from trajcache.services.catalog.models import get_model
from trajcache.services.context import ServiceContext


@pytest.fixture
def replicas(database_url: str) -> Iterator[tuple[TestClient, TestClient]]:
    settings = Settings(database_url=database_url)
    with TestClient(create_app(settings)) as a, TestClient(create_app(settings)) as b:
        assert a.app.state.ctx is not b.app.state.ctx  # type: ignore[attr-defined]
        yield a, b


def index_of(client: TestClient, model_id: str) -> TrajectoryIndex:
    """The replica's index of `model_id` after its next sync."""
    ctx: ServiceContext = client.app.state.ctx  # type: ignore[attr-defined]
    with ctx.sessions() as session:
        model = get_model(session=session, registry=ctx.models, model_id=model_id)
        return ctx.indexes.index(session, model)


def store(client: TestClient, model_id: str, states: list[list[float]]) -> int:
    response = client.post("/v1/trajectories", json={"model_id": model_id, "states": states})
    assert response.status_code == 201, response.text
    return int(response.json()["trajectory_id"])


def test_writes_and_deletes_reach_the_other_replica(
    replicas: tuple[TestClient, TestClient],
) -> None:
    a, b = replicas
    model_id = a.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF}).json()["model_id"]
    # both replicas have loaded (and synced) the model's index before the writes
    assert len(index_of(a, model_id)) == 0
    assert len(index_of(b, model_id)) == 0

    first = store(a, model_id, [[0.0, 0.0], [1.0, 0.5]])
    assert first in index_of(b, model_id)
    assert first in index_of(a, model_id)

    second = store(b, model_id, [[0.2, 0.0], [-1.0, 0.5]])
    assert second in index_of(a, model_id)

    response = b.delete(f"/v1/trajectories/{first}")
    assert response.status_code == 204
    index_a = index_of(a, model_id)
    assert first not in index_a
    assert second in index_a
    assert first not in index_of(b, model_id)
    assert len(index_of(a, model_id)) == len(index_of(b, model_id)) == 1


def test_a_replica_started_later_loads_what_is_there(database_url: str) -> None:
    settings = Settings(database_url=database_url)
    with TestClient(create_app(settings)) as a:
        model_id = a.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF}).json()["model_id"]
        kept = store(a, model_id, [[0.0, 0.0], [1.0, 0.5]])
        dropped = store(a, model_id, [[0.0, 0.1], [1.0, 0.5]])
        assert a.delete(f"/v1/trajectories/{dropped}").status_code == 204
    with TestClient(create_app(settings)) as b:
        index = index_of(b, model_id)
        assert kept in index
        assert dropped not in index
        assert len(index) == 1
