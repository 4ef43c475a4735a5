"""Timed answers and answer quality through the real app (POST /v1/robots/{id}/plan)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, register

CORNER = [[0.0, 0.0], [1.2, 0.0], [0.6, 1.2]]
# A small ball that the spline through CORNER sweeps into (its bulge) and the straight
# segments pass 3 cm away from.
BALL = {"id": "ball", "type": "sphere", "size": [0.005], "pose": {"position": [0.4362, 0, 0.211]}}
VELOCITY = np.array([1.0, 1.0])  # the 2-joint URDF
ACCELERATION = np.array([5.0, 5.0])  # TRAJCACHE_TIMING_JOINT_ACCELERATION default


def _store(client: TestClient, model_id: str, states: list[list[float]]) -> None:
    reply = client.post("/v1/trajectories", json={"model_id": model_id, "states": states})
    assert reply.status_code in (200, 201), reply.text


def _plan(client: TestClient, states: list[list[float]], **options: Any) -> Any:
    body = {"start": states[0], "goal": states[-1], "options": {"fallback": False, **options}}
    return client.post("/v1/robots/robot-1/plan", json=body)


def _points(body: dict[str, Any]) -> tuple[np.ndarray, ...]:
    points = body["joint_trajectory"]["points"]
    return tuple(
        np.array([p[key] for p in points], dtype=float)
        for key in ("time_from_start", "positions", "velocities", "accelerations")
    )


def test_timed_answer_is_a_joint_trajectory_through_every_state_within_limits(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    _store(app_client, model_id, CORNER)
    body = _plan(app_client, CORNER, timing={"method": "toppra"}).json()
    assert body["status"] == "success" and body["source"] == "cache"
    jt = body["joint_trajectory"]
    assert jt["joint_names"] == ["shoulder", "elbow"] and jt["method"] == "toppra"
    assert jt["path"] == "spline"  # no obstacle: the spline is certified
    t, q, v, a = _points(body)
    np.testing.assert_allclose(q, body["states"], atol=1e-9)  # sampled at the key states
    assert t[0] == 0.0 and np.all(np.diff(t) > 0) and t[-1] == pytest.approx(jt["duration_s"])
    np.testing.assert_allclose(v[[0, -1]], 0.0, atol=1e-9)
    assert np.abs(v[1]).max() > 0.05  # passes the corner without stopping
    periodic = _plan(app_client, CORNER, timing={"sample_period_s": 0.01}).json()
    t, q, v, a = _points(periodic)
    np.testing.assert_allclose(np.diff(t)[:-1], 0.01, atol=1e-12)
    assert np.max(np.abs(v) / VELOCITY) <= 1.01 and np.max(np.abs(a) / ACCELERATION) <= 1.01
    quality = periodic["quality"]
    assert quality["duration_s"] == pytest.approx(t[-1])
    assert periodic["timings_ms"]["timing"] > 0


def test_spline_into_an_obstacle_falls_back_to_the_validated_segments(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    _store(app_client, model_id, CORNER)
    assert app_client.put("/v1/robots/robot-1/scene", json={"objects": [BALL]}).status_code == 200
    body = _plan(app_client, CORNER, timing={"path": "spline"}).json()
    assert body["status"] == "success"
    assert body["joint_trajectory"]["path"] == "linear"
    _, q, v, _ = _points(body)
    np.testing.assert_allclose(q, CORNER, atol=1e-9)
    np.testing.assert_allclose(v[1], 0.0, atol=1e-9)  # the straight path stops at the corner


def test_scaling_slows_the_answer_and_jerk_limited_rests_at_every_state(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    _store(app_client, model_id, CORNER)
    fast = _plan(app_client, CORNER, timing={"path": "linear"}).json()
    scaled = {"path": "linear", "velocity_scaling": 0.25, "acceleration_scaling": 0.25}
    slow = _plan(app_client, CORNER, timing=scaled).json()
    assert slow["joint_trajectory"]["duration_s"] > 1.9 * fast["joint_trajectory"]["duration_s"]
    jerk = _plan(app_client, CORNER, timing={"method": "jerk_limited"}).json()
    assert jerk["joint_trajectory"]["method"] == "jerk_limited"
    _, q, v, _ = _points(jerk)
    np.testing.assert_allclose(q, CORNER, atol=1e-9)
    np.testing.assert_allclose(v, 0.0, atol=1e-9)
    none = _plan(app_client, CORNER, timing={"method": "none"}).json()
    assert none["joint_trajectory"] is None and none["quality"]["duration_s"] is None


def test_default_answer_has_cheap_quality_and_full_adds_clearance_and_duration(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    _store(app_client, model_id, CORNER)
    app_client.put("/v1/robots/robot-1/scene", json={"objects": [BALL]})
    basic = _plan(app_client, CORNER).json()
    expected_length = sum(np.linalg.norm(np.diff(np.array(CORNER), axis=0), axis=1))
    assert basic["joint_trajectory"] is None
    assert basic["quality"]["path_length"] == pytest.approx(expected_length)
    assert 0.3 < basic["quality"]["ee_path_length"] < 2.0
    assert basic["quality"]["min_clearance"] is None and basic["quality"]["duration_s"] is None
    full = _plan(app_client, CORNER, quality="full").json()["quality"]
    assert 0.02 < full["min_clearance"] < 0.04  # the ball is 3 cm from the straight segments
    assert full["duration_s"] > 0 and full["path_length"] == pytest.approx(expected_length)
    miss = _plan(app_client, [[0.0, 1.0], [0.5, 1.0]], quality="full").json()
    assert miss["status"] == "miss" and miss["quality"] is None and miss["joint_trajectory"] is None


@pytest.mark.parametrize(
    ("timing", "needle"),
    [
        ({"velocity_scaling": 0}, "velocity_scaling"),
        ({"acceleration_scaling": 1.5}, "acceleration_scaling"),
        ({"velocity_scaling": "fast"}, "velocity_scaling"),
        ({"method": "fastest"}, "method"),
        ({"path": "curvy"}, "path"),
        ({"sample_period_s": 0}, "sample_period_s"),
        ({"sample_period_s": -1}, "sample_period_s"),
        ({"jerk": 5}, "jerk"),
    ],
)
def test_bad_timing_options_are_422_naming_the_field(
    app_client: TestClient, model_id: str, robot_id: str, timing: dict[str, Any], needle: str
) -> None:
    _store(app_client, model_id, CORNER)
    assert_detail(_plan(app_client, CORNER, timing=timing), 422, "options.timing", needle)


def test_bad_quality_option_and_too_many_points_are_422(
    client_factory: ClientFactory,
) -> None:
    client = client_factory(timing_max_points=50)
    model_id = register(client)["model_id"]
    client.put("/v1/robots/robot-1", json={"model_id": model_id})
    _store(client, model_id, CORNER)
    assert_detail(_plan(client, CORNER, quality="best"), 422, "options.quality")
    assert_detail(
        _plan(client, CORNER, timing={"sample_period_s": 0.001}), 422, "sample_period_s", "50"
    )
