"""Plans of a robot that never uploaded a scene: a warning, or a refusal under require_scene."""

from __future__ import annotations

from typing import Any

import yaml
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, register
from trajcache.services.plan.flow import NO_SCENE_WARNING

PATH = [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]
PLAN = {"start": [0.05, 0.0], "goal": [0.95, 0.0], "options": {"fallback": False}}
MOVEIT = {
    "group_name": "arm",
    "start_state": {"joint_state": {"name": ["shoulder", "elbow"], "position": [0.05, 0.0]}},
    "goal_constraints": [
        {
            "joint_constraints": [
                {"joint_name": "shoulder", "position": 0.95},
                {"joint_name": "elbow", "position": 0.0},
            ]
        }
    ],
}


def _robot(client: TestClient) -> str:
    model_id = register(client)["model_id"]
    assert client.put("/v1/robots/r", json={"model_id": model_id}).status_code == 201
    stored = client.post("/v1/trajectories", json={"model_id": model_id, "states": PATH})
    assert stored.status_code in (200, 201), stored.text
    return "/v1/robots/r"


def _motion_plan(client: TestClient) -> dict[str, Any]:
    reply = client.post(
        "/v1/robots/r/motion-plan",
        content=yaml.safe_dump(MOVEIT),
        headers={"content-type": "application/yaml"},
    )
    assert reply.status_code == 200, reply.text
    answer: dict[str, Any] = reply.json()
    return answer


def test_a_robot_without_a_scene_is_warned(app_client: TestClient) -> None:
    url = _robot(app_client)
    body = app_client.post(f"{url}/plan", json=PLAN).json()
    assert body["status"] == "success" and body["warnings"] == [NO_SCENE_WARNING]
    assert "self-collision only" in NO_SCENE_WARNING
    answer = _motion_plan(app_client)
    assert answer["error_code"]["val"] == 1
    assert NO_SCENE_WARNING in answer["warnings"]


def test_an_uploaded_empty_scene_is_the_robots_word(app_client: TestClient) -> None:
    url = _robot(app_client)
    put = app_client.put(f"{url}/scene", json={"objects": []})
    assert put.status_code == 200 and put.json()["version"] == 1  # stored, though empty
    assert app_client.get(f"{url}/scene").json()["version"] == 1
    again = app_client.put(f"{url}/scene", json={"objects": []}).json()
    assert again["version"] == 1  # the same content again: no new version
    body = app_client.post(f"{url}/plan", json=PLAN).json()
    assert body["status"] == "success" and body["warnings"] == []
    assert NO_SCENE_WARNING not in _motion_plan(app_client)["warnings"]


def test_require_scene_refuses_a_robot_without_one(client_factory: ClientFactory) -> None:
    client = client_factory(require_scene=True)
    url = _robot(client)
    assert_detail(client.post(f"{url}/plan", json=PLAN), 409, "'r' has no scene", "PUT")
    answer = _motion_plan(client)
    assert answer["error_code"]["val"] == -22  # COLLISION_CHECKING_UNAVAILABLE
    assert "has no scene" in answer["error_code"]["message"]
    assert answer["trajectory"]["joint_trajectory"]["points"] == []

    assert client.patch(f"{url}/scene", json={"upsert": []}).json()["version"] == 1
    body = client.post(f"{url}/plan", json=PLAN).json()
    assert body["status"] == "success" and body["warnings"] == []
    assert _motion_plan(client)["error_code"]["val"] == 1
