"""The edges of HTTP: content types, methods, and what an error may say."""

from __future__ import annotations

import json

from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail
from trajcache.cli.docs import openapi_document


def _json_only_operations() -> list[tuple[str, str]]:
    """(method, path) of every operation whose body the document declares as JSON only."""
    return [
        (method.upper(), path)
        for path, operations in openapi_document()["paths"].items()
        for method, op in operations.items()
        if list(op.get("requestBody", {}).get("content", {})) == ["application/json"]
    ]


def test_every_json_body_in_another_media_type_is_a_415(app_client: TestClient) -> None:
    operations = _json_only_operations()
    assert {("POST", "/v1/robots/{robot_id}/plan"), ("PATCH", "/v1/robots/{robot_id}/scene")} <= (
        set(operations)
    )
    for method, path in operations:
        url = path.replace("{robot_id}", "robot-1")
        for media in ("text/csv", "application/xml"):
            reply = app_client.request(method, url, content=b"a,b", headers={"content-type": media})
            assert_detail(reply, 415, repr(media), "send application/json")


def test_every_json_only_operation_declares_its_415() -> None:
    paths = openapi_document()["paths"]
    for method, path in _json_only_operations():
        assert "415" in paths[path][method.lower()]["responses"], f"{method} {path}"


def test_a_json_body_without_a_content_type_or_in_a_json_type_is_read(
    app_client: TestClient, robot_id: str
) -> None:
    url = f"/v1/robots/{robot_id}/scene"
    patch = {"upsert": [{"id": "a", "type": "sphere", "size": [0.1]}]}
    bare = app_client.patch(url, content=json.dumps(patch).encode())
    assert "content-type" not in bare.request.headers
    assert bare.status_code == 200, bare.text
    merge = app_client.patch(
        url,
        content=json.dumps({"remove": ["a"]}).encode(),
        headers={"content-type": "application/merge-patch+json; charset=utf-8"},
    )
    assert merge.status_code == 200, merge.text
    assert merge.json()["version"] == 2
    assert app_client.get(url).json()["objects"] == []


def test_a_405_allows_every_method_of_the_path(app_client: TestClient) -> None:
    reply = app_client.delete("/v1/robots/robot-1/scene")
    assert_detail(reply, 405, "DELETE", "allowed: GET, PUT, PATCH")
    assert reply.headers["allow"] == "GET, PUT, PATCH"
    assert app_client.post("/v1/trajectories/7").headers["allow"] == "GET, DELETE"
    assert app_client.put("/v1/robots/robot-1/plan").headers["allow"] == "POST"


def test_a_robot_id_of_only_dots_is_a_422_naming_it_on_every_robot_route(
    app_client: TestClient, model_id: str
) -> None:
    paths = openapi_document()["paths"]
    operations = [(m.upper(), p) for p, ops in paths.items() if "{robot_id}" in p for m in ops]
    assert len(operations) == 10
    for method, path in operations:
        for robot_id in (".", "..", "..."):
            encoded = robot_id.replace(".", "%2E")  # a client would resolve the dot segments
            url = path.replace("{robot_id}", encoded).replace("{version}", "1")
            reply = app_client.request(method, url, json={"model_id": model_id})
            assert_detail(reply, 422, "path.robot_id", f"robot id {robot_id!r}", "only dots")
    store = {"model_id": model_id, "states": [[0, 0], [0.1, 0]], "robot_id": ".."}
    assert_detail(app_client.post("/v1/trajectories", json=store), 422, "robot id '..'")
    for robot_id in ("..a", "v1.2", ".arm"):
        assert (
            app_client.put(f"/v1/robots/{robot_id}", json={"model_id": model_id}).status_code == 201
        )
