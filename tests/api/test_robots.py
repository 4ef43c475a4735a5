"""PUT/GET /v1/robots/{robot_id}: create, re-point, validation."""

from __future__ import annotations

from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail, register


def test_create_then_repoint(app_client: TestClient, model_id: str) -> None:
    created = app_client.put("/v1/robots/arm-1", json={"model_id": model_id})
    assert created.status_code == 201, created.text
    body = created.json()
    assert body["robot_id"] == "arm-1"
    assert body["model_id"] == model_id
    assert body["scene_version"] == 0

    same = app_client.put("/v1/robots/arm-1", json={"model_id": model_id})
    assert same.status_code == 200
    assert same.json()["model_id"] == model_id

    other = register(app_client, base="planar")["model_id"]
    moved = app_client.put("/v1/robots/arm-1", json={"model_id": other})
    assert moved.status_code == 200
    assert moved.json()["model_id"] == other
    assert app_client.get("/v1/robots/arm-1").json()["model_id"] == other


def test_repoint_keeps_the_scene(app_client: TestClient, model_id: str, robot_id: str) -> None:
    scene = {"objects": [{"id": "b", "type": "sphere", "size": [0.1]}]}
    assert app_client.put(f"/v1/robots/{robot_id}/scene", json=scene).json()["version"] == 1
    other = register(app_client, base="planar")["model_id"]
    assert app_client.put(f"/v1/robots/{robot_id}", json={"model_id": other}).status_code == 200
    assert app_client.get(f"/v1/robots/{robot_id}").json()["scene_version"] == 1


def test_unknown_robot_and_model_are_404(app_client: TestClient, model_id: str) -> None:
    assert_detail(app_client.get("/v1/robots/ghost"), 404, "ghost")
    assert_detail(app_client.put("/v1/robots/r1", json={"model_id": "f" * 64}), 404, "robot model")
    assert_detail(app_client.get("/v1/robots/r1"), 404)  # the failed PUT created nothing


def test_bad_robot_input_is_422(app_client: TestClient, model_id: str) -> None:
    assert_detail(
        app_client.put("/v1/robots/bad%20id", json={"model_id": model_id}), 422, "robot id"
    )
    assert_detail(
        app_client.put("/v1/robots/" + "r" * 129, json={"model_id": model_id}), 422, "1-128"
    )
    assert_detail(app_client.put("/v1/robots/r1", json={}), 422, "body.model_id")
    assert_detail(
        app_client.put("/v1/robots/r1", json={"model_id": model_id, "x": 1}), 422, "body.x"
    )


def test_robot_ids_with_allowed_punctuation(app_client: TestClient, model_id: str) -> None:
    robot_id = "fleet:A_1.arm-2"
    response = app_client.put(f"/v1/robots/{robot_id}", json={"model_id": model_id})
    assert response.status_code == 201, response.text
    assert app_client.get(f"/v1/robots/{robot_id}").json()["robot_id"] == robot_id
