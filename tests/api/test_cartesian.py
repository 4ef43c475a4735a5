"""POST /v1/robots/{id}/cartesian-path through the real app, natively and as MoveIt's
GetCartesianPath, on example-robot-data's Panda: every state's hand position checked with
yourdfpy (not the service's kinematics) against the line and the answer's stated bound."""

from __future__ import annotations

import io
import itertools
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from scipy.spatial.transform import Rotation
from yourdfpy import URDF
from yourdfpy.urdf import filename_handler_null

from tests.api.conftest import assert_detail
from tests.api.test_real_robots import READY, _register, _robot
from trajcache.geometry.model.cartesian_bound import distance_to_segment
from trajcache.reference.example_robots import ROBOTS

LINK = "panda_hand"
ARM = [f"panda_joint{k}" for k in range(1, 8)]


@pytest.fixture(scope="module")
def panda_fk() -> Any:
    return URDF.load(
        io.BytesIO(ROBOTS["panda"].urdf.encode()),
        build_scene_graph=True,
        load_meshes=False,
        filename_handler=filename_handler_null,
    )


@pytest.fixture
def robot(app_client: TestClient) -> str:
    robot_id = _robot(app_client, _register(app_client, ROBOTS["panda"])["model_id"], "panda")
    put = app_client.put(f"/v1/robots/{robot_id}/scene", json={"objects": []})
    assert put.status_code == 200, put.text
    return robot_id


def hand(fk: Any, state: list[float]) -> np.ndarray:
    fk.update_cfg(dict(zip(ARM, state, strict=True)))
    return np.asarray(fk.get_transform(LINK, fk.base_link))


def approach(fk: Any, distance: float = 0.10) -> tuple[np.ndarray, dict[str, Any]]:
    """The hand's pose at READY and a waypoint `distance` along its approach axis (its z)."""
    pose = hand(fk, READY)
    end = pose[:3, 3] + distance * pose[:3, 2]
    quat = Rotation.from_matrix(pose[:3, :3]).as_quat()
    return pose, {"position": end.tolist(), "orientation": quat.tolist()}


def cartesian(client: TestClient, robot: str, body: dict[str, Any]) -> Any:
    return client.post(f"/v1/robots/{robot}/cartesian-path", json=body)


def native(waypoint: dict[str, Any], **fields: Any) -> dict[str, Any]:
    return {"start": READY, "link": LINK, "waypoints": [waypoint], **fields}


def test_a_straight_approach_reaches_fraction_one_on_its_line(
    app_client: TestClient, robot: str, panda_fk: Any
) -> None:
    pose, waypoint = approach(panda_fk)
    reply = cartesian(app_client, robot, native(waypoint))
    assert reply.status_code == 200, reply.text
    body = reply.json()
    assert body["status"] == "complete" and body["fraction"] == 1.0
    assert body["source"] == "computed" and body["warnings"] == []
    assert isinstance(body["path_id"], int)  # stored: it reached the whole path
    assert len(body["states"]) == 11 and body["states"][0] == pytest.approx(READY)
    assert 0 < body["max_deviation_m"] < 2e-3
    end = np.array(waypoint["position"])
    t = np.linspace(0.0, 1.0, 21)
    states = np.array(body["states"])
    for a, b in itertools.pairwise(states):  # FK between samples, by yourdfpy
        points = np.array([hand(panda_fk, list(a + s * (b - a)))[:3, 3] for s in t])
        assert distance_to_segment(points, pose[:3, 3], end).max() <= body["max_deviation_m"]
    assert np.linalg.norm(hand(panda_fk, body["states"][-1])[:3, 3] - end) <= 1e-4
    timed = body["joint_trajectory"]
    assert timed["duration_s"] > 0 and timed["points"][-1]["positions"] == pytest.approx(
        body["states"][-1]
    )


def test_a_move_into_an_obstacle_stops_short_and_names_it(
    app_client: TestClient, robot: str, panda_fk: Any
) -> None:
    pose, waypoint = approach(panda_fk)
    ahead = pose[:3, 3] + 0.17 * pose[:3, 2]  # the fingertips (10 cm on) meet it half way
    box = {"id": "crate", "type": "box", "size": [0.1, 0.1, 0.02]}
    box["pose"] = {"position": ahead.tolist()}
    assert app_client.put(f"/v1/robots/{robot}/scene", json={"objects": [box]}).status_code == 200
    body = cartesian(app_client, robot, native(waypoint, avoid_collisions=False)).json()
    assert body["status"] in ("collision", "too_close") and 0.0 < body["fraction"] < 1.0
    assert "crate" in body["message"] and body["path_id"] is None  # a part is never stored
    assert any("avoid_collisions=false is not honoured" in w for w in body["warnings"])


def test_a_jump_threshold_stops_a_jump(app_client: TestClient, robot: str, panda_fk: Any) -> None:
    _, waypoint = approach(panda_fk)
    body = cartesian(app_client, robot, native(waypoint, revolute_jump_threshold=1e-3)).json()
    assert body["status"] == "joint_jump" and body["fraction"] == 0.0
    assert "jumps by" in body["message"] and len(body["states"]) == 1


def test_malformed_and_refused_fields_are_422s_that_name_them(
    app_client: TestClient, robot: str, panda_fk: Any
) -> None:
    _, waypoint = approach(panda_fk)
    assert_detail(cartesian(app_client, robot, native(waypoint, max_step=0)), 422, "max_step")
    moveit = moveit_request(waypoint)
    constrained = {**moveit, "path_constraints": {"orientation_constraints": [{"link_name": LINK}]}}
    assert_detail(cartesian(app_client, robot, constrained), 422, "path_constraints")
    fast = {**moveit, "max_cartesian_speed": 0.2}
    assert_detail(cartesian(app_client, robot, fast), 422, "max_cartesian_speed")
    far = native({"position": [100.0, 0.0, 0.0], "orientation": waypoint["orientation"]})
    assert_detail(cartesian(app_client, robot, far), 422, "waypoints", "samples")
    bad = native({"position": waypoint["position"], "orientation": [0, 0, 0, 0.5]})
    assert_detail(cartesian(app_client, robot, bad), 422, "waypoints[0].orientation")


def moveit_request(waypoint: dict[str, Any], **fields: Any) -> dict[str, Any]:
    return {
        "header": {"frame_id": "panda_link0"},
        "start_state": {"joint_state": {"name": ARM, "position": READY}},
        "group_name": "panda_arm",
        "link_name": LINK,
        "waypoints": [waypoint],
        "max_step": 0.01,
        "jump_threshold": 0.0,
        **fields,
    }


def test_the_moveit_form_answers_with_a_timed_solution_and_the_fraction(
    app_client: TestClient, robot: str, panda_fk: Any
) -> None:
    _, waypoint = approach(panda_fk)
    reply = cartesian(app_client, robot, moveit_request(waypoint, max_velocity_scaling_factor=0.5))
    assert reply.status_code == 200, reply.text
    body = reply.json()
    assert body["error_code"]["val"] == 1 and body["fraction"] == 1.0
    assert body["start_state"]["joint_state"]["position"] == pytest.approx(READY)
    points = body["solution"]["joint_trajectory"]["points"]
    assert body["solution"]["joint_trajectory"]["joint_names"] == ARM
    assert points[0]["time_from_start"] == {"sec": 0, "nanosec": 0} and len(points) > 2
    end = hand(panda_fk, points[-1]["positions"])[:3, 3]
    assert np.linalg.norm(end - np.array(waypoint["position"])) <= 1e-4
    warnings = body["trajcache"]["warnings"]
    assert any("group_name" in w for w in warnings)
    assert any("avoid_collisions=false" in w for w in warnings)  # MoveIt's default is false


def test_the_moveit_form_keeps_success_when_the_path_stops_short(
    app_client: TestClient, robot: str, panda_fk: Any
) -> None:
    pose, _ = approach(panda_fk)
    far = {"position": (pose[:3, 3] + [2.0, 0.0, 0.0]).tolist(), "orientation": [1, 0, 0, 0]}
    body = cartesian(app_client, robot, moveit_request(far, max_step=0.05)).json()
    assert body["error_code"]["val"] == 1 and 0.0 <= body["fraction"] < 1.0
    assert body["trajcache"]["status"] == "no_ik_solution"
    unknown = moveit_request(far, header={"frame_id": "camera"})
    body = cartesian(app_client, robot, unknown).json()
    assert body["error_code"]["val"] == -21 and "header.frame_id" in body["error_code"]["message"]


def test_a_repeat_is_served_from_the_cache_within_its_tolerances(
    app_client: TestClient, robot: str, panda_fk: Any
) -> None:
    _, waypoint = approach(panda_fk)
    first = cartesian(app_client, robot, native(waypoint)).json()
    again = cartesian(app_client, robot, native(waypoint)).json()
    assert again["source"] == "cache" and again["path_id"] == first["path_id"]
    assert again["states"] == first["states"] and again["fraction"] == 1.0
    moved = [v + 5e-4 for v in READY]  # within the default 1e-3 rad
    near = cartesian(app_client, robot, {**native(waypoint), "start": moved}).json()
    assert near["source"] == "cache" and near["states"][0] == pytest.approx(moved)
    assert near["states"][1:] == first["states"][1:]
    shifted = {**waypoint, "position": [p + 0.003 for p in waypoint["position"]]}
    body = cartesian(app_client, robot, native(shifted, cache={"store": False})).json()
    assert body["source"] == "computed"  # 5 mm away: beyond the default 1 mm
    assert body["path_id"] is None  # not stored, as asked
    widened = native(shifted, cache={"position_tolerance": 0.006})
    body = cartesian(app_client, robot, widened).json()
    assert body["source"] == "cache" and body["path_id"] == first["path_id"]
    assert body["max_deviation_m"] > first["max_deviation_m"]  # measured from the request's line
    other = cartesian(app_client, robot, native(waypoint, max_step=0.02)).json()
    assert other["source"] == "computed"  # other parameters: another path


def test_a_repeat_after_a_scene_change_that_blocks_it_is_not_served_from_the_cache(
    app_client: TestClient, robot: str, panda_fk: Any
) -> None:
    pose, waypoint = approach(panda_fk)
    assert cartesian(app_client, robot, native(waypoint)).json()["fraction"] == 1.0
    ahead = pose[:3, 3] + 0.17 * pose[:3, 2]
    box = {"id": "crate", "type": "box", "size": [0.1, 0.1, 0.02]}
    box["pose"] = {"position": ahead.tolist()}
    assert app_client.put(f"/v1/robots/{robot}/scene", json={"objects": [box]}).status_code == 200
    body = cartesian(app_client, robot, native(waypoint)).json()
    assert body["source"] == "computed" and body["fraction"] < 1.0 and "crate" in body["message"]
