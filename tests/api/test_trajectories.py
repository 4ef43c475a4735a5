"""POST/GET/DELETE /v1/trajectories: storing, dedupe, listing, deletion and bad input."""

from __future__ import annotations

from typing import Any

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, ctx_of, register
from trajcache.db.models import Trajectory, TrajectoryTombstone

STATES = [[0.0, 0.0], [0.5, -0.2], [1.0, 0.3]]


def store(client: TestClient, model_id: str, states: Any = None, **fields: Any) -> Any:
    body = {"model_id": model_id, "states": STATES if states is None else states, **fields}
    return client.post("/v1/trajectories", json=body)


def test_store_get_and_dedupe(app_client: TestClient, model_id: str, robot_id: str) -> None:
    response = store(
        app_client,
        model_id,
        source="sim",
        robot_id=robot_id,
        scene_hash="ab" * 32,
        env={"door": 0.5},
        planning_time_ms=12.5,
    )
    assert response.status_code == 201, response.text
    created = response.json()
    assert created["created"] is True
    trajectory_id = created["trajectory_id"]

    again = store(app_client, model_id, source="real")
    assert again.status_code == 200
    assert again.json() == {"trajectory_id": trajectory_id, "created": False}

    got = app_client.get(f"/v1/trajectories/{trajectory_id}").json()
    assert got["states"] == STATES
    assert got["start"] == STATES[0] and got["goal"] == STATES[-1]
    assert (got["n_states"], got["dof"]) == (3, 2)
    assert got["source"] == "sim"
    assert got["robot_id"] == robot_id
    assert got["scene_hash"] == "ab" * 32
    assert got["env"] == {"door": 0.5}
    assert got["planning_time_ms"] == 12.5
    assert got["hits"] == 0


def test_list_filters_and_pages(app_client: TestClient, model_id: str, robot_id: str) -> None:
    other = register(app_client, base="planar")["model_id"]
    ids = []
    for i in range(5):
        states = [[0.0, 0.0], [0.1 * i, 0.1]]
        source = "sim" if i % 2 else "real"
        response = store(app_client, model_id, states, source=source)
        assert response.status_code == 201, response.text
        ids.append(response.json()["trajectory_id"])
    app_client.put("/v1/robots/mobile-1", json={"model_id": other})
    planar = [[0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.5, 0.2, 0.1]]
    response = store(app_client, other, planar, robot_id="mobile-1")
    assert response.status_code == 201, response.text
    other_id = response.json()

    everything = app_client.get("/v1/trajectories").json()
    assert everything["total"] == 6
    assert "states" not in everything["items"][0]

    page = app_client.get(f"/v1/trajectories?model_id={model_id}&limit=2&offset=1").json()
    assert (page["total"], page["limit"], page["offset"]) == (5, 2, 1)
    assert [t["trajectory_id"] for t in page["items"]] == ids[1:3]

    sims = app_client.get(f"/v1/trajectories?model_id={model_id}&source=sim").json()
    assert [t["trajectory_id"] for t in sims["items"]] == [ids[1], ids[3]]
    mobile = app_client.get("/v1/trajectories?robot_id=mobile-1").json()
    assert [t["trajectory_id"] for t in mobile["items"]] == [other_id["trajectory_id"]]
    assert app_client.get(f"/v1/trajectories?robot_id={robot_id}").json()["total"] == 0
    assert app_client.get("/v1/trajectories?model_id=nope").json() == {
        "items": [],
        "total": 0,
        "limit": 100,
        "offset": 0,
    }


def test_robot_of_another_model_is_409(app_client: TestClient, robot_id: str) -> None:
    other = register(app_client, base="planar")["model_id"]
    planar = [[0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.5, 0.2, 0.1]]
    app_client.put(f"/v1/robots/{robot_id}", json={"model_id": other})
    first = app_client.get(f"/v1/robots/{robot_id}").json()["model_id"]
    assert first == other
    model_id = register(app_client)["model_id"]
    assert_detail(store(app_client, model_id, robot_id=robot_id), 409, robot_id)
    assert store(app_client, other, planar, robot_id=robot_id).status_code == 201


def test_page_size_limit(client_factory: ClientFactory) -> None:
    client = client_factory(max_page_size=3)
    assert client.get("/v1/trajectories?limit=3").status_code == 200
    assert client.get("/v1/trajectories").json()["limit"] == 3
    assert_detail(client.get("/v1/trajectories?limit=4"), 422, "max_page_size=3")
    assert_detail(client.get("/v1/robot-models?limit=4"), 422, "max_page_size=3")
    assert_detail(client.get("/v1/trajectories?limit=0"), 422, "query.limit")
    assert_detail(client.get("/v1/trajectories?offset=-1"), 422, "query.offset")
    assert_detail(client.get("/v1/trajectories?source=dream"), 422, "query.source")


def test_delete_leaves_a_tombstone(app_client: TestClient, model_id: str) -> None:
    trajectory_id = store(app_client, model_id).json()["trajectory_id"]
    response = app_client.delete(f"/v1/trajectories/{trajectory_id}")
    assert response.status_code == 204
    assert response.content == b""
    assert_detail(app_client.get(f"/v1/trajectories/{trajectory_id}"), 404, str(trajectory_id))
    assert_detail(app_client.delete(f"/v1/trajectories/{trajectory_id}"), 404)
    with ctx_of(app_client).sessions() as session:
        assert session.get(Trajectory, trajectory_id) is None
        tombstones = session.execute(
            sa.select(TrajectoryTombstone.trajectory_id, TrajectoryTombstone.model_id)
        ).all()
    assert [tuple(t) for t in tombstones] == [(trajectory_id, model_id)]
    # stored again after deletion: a new row with a new id
    again = store(app_client, model_id).json()
    assert again["created"] is True and again["trajectory_id"] > trajectory_id


@pytest.mark.parametrize(
    ("states", "needles"),
    [
        ([[0.0, 0.0, 0.0], [0.1, 0.1, 0.1]], ("3 values", "expected 2", "shoulder, elbow")),
        ([[0.0, 0.0], [0.1]], ("state",)),
        ([[0.0, 0.0]], ("at least 2",)),
        ([[0.0, 0.0], [0.0, 1.9]], ("elbow", "out of joint limits")),
        ([[0.0, 0.0], [2.5, 0.0]], ("shoulder",)),
        ([], ("at least 2",)),
    ],
)
def test_bad_states_are_422(
    app_client: TestClient, model_id: str, states: Any, needles: tuple[str, ...]
) -> None:
    assert_detail(store(app_client, model_id, states), 422, *needles)
    assert app_client.get("/v1/trajectories").json()["total"] == 0


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity", "1e309"])
def test_non_finite_json_tokens_are_422(app_client: TestClient, model_id: str, token: str) -> None:
    raw = f'{{"model_id": "{model_id}", "states": [[0.0, 0.0], [{token}, 0.1]]}}'
    response = app_client.post(
        "/v1/trajectories", content=raw, headers={"content-type": "application/json"}
    )
    assert_detail(response, 422, "body.states[1][0]", "finite")


def test_other_bad_input(app_client: TestClient, model_id: str) -> None:
    assert_detail(store(app_client, "0" * 64), 404, "robot model")
    assert_detail(store(app_client, model_id, robot_id="ghost"), 404, "ghost")
    assert_detail(store(app_client, model_id, source="dream"), 422, "body.source")
    assert_detail(store(app_client, model_id, robot_id="bad id"), 422, "body.robot_id")
    assert_detail(store(app_client, model_id, env={"door": "open"}), 422, "body.env.door")
    assert_detail(store(app_client, model_id, colour=1), 422, "body.colour")
    assert_detail(store(app_client, model_id, states="[[0, 0]]"), 422, "body.states")
    assert_detail(app_client.get("/v1/trajectories/0"), 422, "path.trajectory_id")
    assert_detail(app_client.get("/v1/trajectories/abc"), 422, "path.trajectory_id")
    assert_detail(app_client.get("/v1/trajectories/999"), 404, "999")


def test_state_count_limit_is_413(client_factory: ClientFactory) -> None:
    client = client_factory(max_trajectory_states=3)
    model_id = register(client)["model_id"]
    assert store(client, model_id, STATES).status_code == 201
    four = [*STATES, [0.0, 0.0]]
    assert_detail(store(client, model_id, four), 413, "max_trajectory_states=3")
