"""A written scene's validator is built once the write is answered (`services.plan.prepare`),
under the key a request then uses: the request builds none of its own."""

from __future__ import annotations

import logging
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import ctx_of, register
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation import validator as validator_module
from trajcache.services.plan.prepare import prepare_scene

BOX = {
    "id": "box",
    "type": "box",
    "size": [0.2, 0.2, 0.2],
    "pose": {"position": [1.5, 1.5, 0.0], "orientation": [0.0, 0.0, 0.0, 1.0]},
}
PLAN = {"start": [0.05, 0.0], "goal": [0.95, 0.0], "options": {"fallback": False}}


def test_a_new_scene_has_its_validator_before_the_first_request(
    app_client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    model_id = register(app_client)["model_id"]
    assert app_client.put("/v1/robots/r", json={"model_id": model_id}).status_code == 201
    stored = app_client.post(
        "/v1/trajectories", json={"model_id": model_id, "states": [[0.0, 0.0], [1.0, 0.0]]}
    )
    assert stored.status_code in (200, 201), stored.text
    built: list[str | None] = []  # the scene hash of each validator built
    real = validator_module.build_validator

    def build(model: RobotModel, scene: Scene, *args: Any, **kwargs: Any) -> Any:
        built.append(scene.hash)
        return real(model, scene, *args, **kwargs)

    monkeypatch.setattr(validator_module, "build_validator", build)
    put = app_client.put("/v1/robots/r/scene", json={"objects": [BOX]})
    assert put.status_code == 200, put.text
    assert built == [put.json()["hash"]]  # built with the write, before any request
    answer = app_client.post("/v1/robots/r/plan", json=PLAN).json()
    assert answer["status"] == "success" and answer["source"] == "cache", answer
    assert len(built) == 1  # the hit found it ready
    moved = {**BOX, "pose": {**BOX["pose"], "position": [1.5, -1.5, 0.0]}}
    patched = app_client.patch("/v1/robots/r/scene", json={"upsert": [moved]})
    assert patched.status_code == 200, patched.text
    assert built[1:] == [patched.json()["hash"]]  # a patch's too
    assert app_client.post("/v1/robots/r/plan", json=PLAN).json()["source"] == "cache"
    assert len(built) == 2


def test_a_failed_preparation_is_logged_never_raised(
    app_client: TestClient, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.WARNING):
        prepare_scene(ctx_of(app_client), "nobody")
    assert "preparing robot 'nobody'" in caplog.text
    assert len(ctx_of(app_client).validators.validators) == 0
