"""Model configuration for timing (acceleration/jerk limits, end-effector link) and the quality
columns of stored trajectories, through the real app."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail, register
from tests.robots import TWO_JOINT_URDF

BALL = {"id": "ball", "type": "sphere", "size": [0.05], "pose": {"position": [0.4, 0.0, 0.2]}}


def _detail(client: TestClient, model_id: str) -> dict[str, Any]:
    reply = client.get(f"/v1/robot-models/{model_id}")
    assert reply.status_code == 200, reply.text
    body: dict[str, Any] = reply.json()
    return body


def test_limits_given_at_registration_are_used_and_shown(app_client: TestClient) -> None:
    model_id = register(app_client, acceleration_limits={"elbow": 3.0}, jerk_limits=20)["model_id"]
    body = _detail(app_client, model_id)
    assert body["acceleration_limits"] == [5.0, 3.0]  # shoulder: the service default
    assert body["jerk_limits"] == [20.0, 20.0]
    assert body["end_effector_link"] == "fore"  # tip of the chain
    assert body["velocity_limits"] == [1.0, 1.0]


def test_timing_uses_the_registered_acceleration_limits(app_client: TestClient) -> None:
    model_id = register(app_client, acceleration_limits=0.5)["model_id"]
    app_client.put("/v1/robots/robot-1", json={"model_id": model_id})
    app_client.post("/v1/trajectories", json={"model_id": model_id, "states": [[0, 0], [1, 1]]})
    options = {"fallback": False, "timing": {"sample_period_s": 0.01}}
    body = app_client.post(
        "/v1/robots/robot-1/plan", json={"start": [0, 0], "goal": [1, 1], "options": options}
    ).json()
    points = body["joint_trajectory"]["points"]
    accelerations = np.array([p["accelerations"] for p in points])
    assert np.abs(accelerations).max() == pytest.approx(0.5, rel=1e-3)
    # 1 rad at ≤ 0.5 rad/s² from rest to rest takes at least 2·sqrt(1 / 0.5) s
    assert body["joint_trajectory"]["duration_s"] >= 2 * np.sqrt(2.0) - 1e-6


def test_configuration_is_fixed_at_first_registration(app_client: TestClient) -> None:
    model_id = register(app_client, acceleration_limits=2.0)["model_id"]
    again = app_client.post(
        "/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "acceleration_limits": 2.0}
    )
    assert again.status_code == 200 and again.json()["model_id"] == model_id
    plain = app_client.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF})
    assert plain.status_code == 200
    assert _detail(app_client, model_id)["acceleration_limits"] == [2.0, 2.0]
    other = app_client.post(
        "/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "acceleration_limits": 3.0}
    )
    assert_detail(other, 409, "acceleration_limits", "fixed")
    link = app_client.post(
        "/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "end_effector_link": "upper"}
    )
    assert_detail(link, 409, "end_effector_link")


@pytest.mark.parametrize(
    ("fields", "needles"),
    [
        ({"acceleration_limits": {"wrist": 1.0}}, ("wrist", "shoulder")),
        ({"acceleration_limits": 0}, ("acceleration_limits",)),
        ({"jerk_limits": {"elbow": -2}}, ("jerk_limits", "elbow")),
        ({"acceleration_limits": "fast"}, ("acceleration_limits",)),
        ({"base": "planar", "acceleration_limits": {"base_x": 1.0}}, ("TRAJCACHE_TIMING_BASE",)),
        ({"end_effector_link": "nozzle"}, ("nozzle", "fore")),
    ],
)
def test_bad_configuration_is_422(
    app_client: TestClient, fields: dict[str, Any], needles: tuple[str, ...]
) -> None:
    reply = app_client.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF, **fields})
    assert_detail(reply, 422, *needles)


def test_form_registration_takes_limits_as_a_number_or_json(app_client: TestClient) -> None:
    reply = app_client.post(
        "/v1/robot-models",
        data={
            "urdf": TWO_JOINT_URDF,
            "acceleration_limits": '{"shoulder": 4}',
            "jerk_limits": "30",
            "end_effector_link": "upper",
        },
    )
    assert reply.status_code == 201, reply.text
    body = _detail(app_client, reply.json()["model_id"])
    assert body["acceleration_limits"] == [4.0, 5.0] and body["jerk_limits"] == [30.0, 30.0]
    assert body["end_effector_link"] == "upper"
    bad = app_client.post(
        "/v1/robot-models", data={"urdf": TWO_JOINT_URDF, "acceleration_limits": "{shoulder"}
    )
    assert_detail(bad, 422, "acceleration_limits")


def test_stored_trajectories_carry_quality_columns(app_client: TestClient) -> None:
    model_id = register(app_client)["model_id"]
    app_client.put("/v1/robots/robot-1", json={"model_id": model_id})
    scene = app_client.put("/v1/robots/robot-1/scene", json={"objects": [BALL]}).json()
    states = [[0.0, 0.0], [0.5, 0.2], [0.2, 0.6]]
    with_scene = app_client.post(
        "/v1/trajectories",
        json={"model_id": model_id, "states": states, "scene_hash": scene["hash"]},
    ).json()["trajectory_id"]
    without = app_client.post(
        "/v1/trajectories", json={"model_id": model_id, "states": states[:2]}
    ).json()["trajectory_id"]
    got = app_client.get(f"/v1/trajectories/{with_scene}").json()
    expected = sum(np.linalg.norm(np.diff(np.array(states), axis=0), axis=1))
    assert got["length"] == pytest.approx(expected)
    assert 0.1 < got["ee_length"] < 1.0 and got["duration_s"] > 0
    assert 0.0 < got["min_clearance"] < 0.3
    other = app_client.get(f"/v1/trajectories/{without}").json()
    assert other["min_clearance"] is None and other["duration_s"] > 0
