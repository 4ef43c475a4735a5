"""What the 3D view draws beyond the robot: a plan event's goal pose (a frame marker) and a
Cartesian path's lines (a polyline through its start and waypoints), through the real app."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from scipy.spatial.transform import Rotation

from tests.api.conftest import assert_detail, ctx_of
from tests.api.test_cartesian import LINK, approach, cartesian, hand, native, panda_fk  # noqa: F401
from tests.api.test_plan_pose import GOAL, START, arm, plan, robot, target  # noqa: F401
from tests.api.test_real_robots import READY, _register, _robot
from trajcache.reference.example_robots import ROBOTS


def event_view(client: TestClient, robot_id: str) -> dict[str, Any]:
    ctx_of(client).records.flush()
    events = client.get("/v1/plan-events", params={"robot_id": robot_id}).json()["items"]
    assert events, "the plan left no event"
    reply = client.get(f"/v1/view/plan-events/{events[0]['event_id']}")
    assert reply.status_code == 200, reply.text
    return dict(reply.json())


def test_a_pose_goals_event_view_carries_the_pose(robot: TestClient, arm: Any) -> None:  # noqa: F811
    goal = target(arm, GOAL)
    assert plan(robot, goal, fallback=True)["status"] == "success"
    view = event_view(robot, "r1")
    assert view["goal_pose"] == {**goal, "position": pytest.approx(goal["position"]),
                                 "orientation": pytest.approx(goal["orientation"])}  # fmt: skip
    assert view["cartesian"] is None


def test_a_state_goals_event_view_has_no_pose(robot: TestClient) -> None:  # noqa: F811
    body = {"start": START, "goal": GOAL, "options": {"fallback": True}}
    assert robot.post("/v1/robots/r1/plan", json=body).json()["status"] == "success"
    assert event_view(robot, "r1")["goal_pose"] is None


def test_a_cartesian_paths_view_carries_its_lines(
    app_client: TestClient,
    panda_fk: Any,  # noqa: F811
) -> None:
    robot_id = _robot(app_client, _register(app_client, ROBOTS["panda"])["model_id"], "panda")
    assert app_client.put(f"/v1/robots/{robot_id}/scene", json={"objects": []}).status_code == 200
    pose, waypoint = approach(panda_fk)
    answer = cartesian(app_client, robot_id, native(waypoint)).json()
    reply = app_client.get(f"/v1/view/cartesian-paths/{answer['path_id']}")
    assert reply.status_code == 200, reply.text
    view = reply.json()
    lines = view["cartesian"]
    assert lines["link"] == LINK and len(lines["poses"]) == 2
    start, end = np.array(lines["poses"])
    assert start[:3] == pytest.approx(pose[:3, 3], abs=1e-5)  # the hand at READY, by yourdfpy
    turn = Rotation.from_quat(start[3:]).inv() * Rotation.from_matrix(pose[:3, :3])
    assert turn.magnitude() < 1e-5
    assert end.tolist() == pytest.approx(
        [*waypoint["position"], *waypoint["orientation"]], abs=1e-6
    )
    assert view["key_states"] == answer["states"] and view["key_states"][0] == pytest.approx(READY)
    assert view["frames"]["count"] > 1 and view["scene"] is None and view["goal_pose"] is None
    assert any("without a scene" in note for note in view["notes"])
    assert_detail(app_client.get("/v1/view/cartesian-paths/999"), 404, "Cartesian path 999")
