"""POST /v1/robots/{id}/motion-plan through the real app: MoveIt's messages over the plan flow."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, register
from tests.api.test_fallback import WALL_SCENE
from tests.waiting import SOLVABLE
from trajcache.api.moveit import MotionPlanResponseOut

ROOT = Path(__file__).resolve().parents[2]
START, GOAL = [0.0, 0.0], [1.0, 0.5]
YAML = {"content-type": "application/yaml"}
# In the upper arm's reach at shoulder 0: a start there collides, a goal there too.
BLOCKER = {
    "id": "blocker",
    "type": "box",
    "size": [0.1, 0.1, 0.1],
    "pose": {"position": [0.0, 0.0, 0.3]},
}


def _joints(names: list[str], values: list[float]) -> list[dict[str, Any]]:
    return [{"joint_name": n, "position": v} for n, v in zip(names, values, strict=True)]


def _request(start: list[float] = START, goal: list[float] = GOAL, **fields: Any) -> dict[str, Any]:
    """A MotionPlanRequest of the 2-joint arm, as a rosbridge-style dict."""
    names = ["shoulder", "elbow"]
    return {
        "group_name": "arm",
        "start_state": {"joint_state": {"name": names, "position": start}},
        "goal_constraints": [{"joint_constraints": _joints(names, goal)}],
        **fields,
    }


def _post(client: TestClient, body: dict[str, Any] | str, robot: str = "robot-1") -> Any:
    text = body if isinstance(body, str) else yaml.safe_dump(body)
    return client.post(f"/v1/robots/{robot}/motion-plan", content=text, headers=YAML)


def _answer(client: TestClient, body: dict[str, Any] | str, robot: str = "robot-1") -> Any:
    reply = _post(client, body, robot)
    assert reply.status_code == 200, reply.text
    answer = reply.json()
    MotionPlanResponseOut.model_validate(answer)  # the documented shape
    return answer


def _store(client: TestClient, model_id: str, states: list[list[float]]) -> None:
    reply = client.post("/v1/trajectories", json={"model_id": model_id, "states": states})
    assert reply.status_code in (200, 201), reply.text


def _points(answer: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (s), positions and velocities of the answer's joint trajectory."""
    points = answer["trajectory"]["joint_trajectory"]["points"]
    stamps = [p["time_from_start"] for p in points]
    assert all(0 <= s["nanosec"] < 1_000_000_000 for s in stamps)
    times = np.array([s["sec"] + s["nanosec"] * 1e-9 for s in stamps])
    positions = np.array([p["positions"] for p in points])
    velocities = np.array([p["velocities"] for p in points])
    return times, positions, velocities


def _code(answer: dict[str, Any]) -> int:
    return int(answer["error_code"]["val"])


def test_yaml_request_is_planned_then_served_from_the_cache(
    client_factory: ClientFactory,
) -> None:
    client = client_factory(worker_processes=1, **SOLVABLE)
    model_id = register(client)["model_id"]
    assert client.put("/v1/robots/robot-1", json={"model_id": model_id}).status_code == 201
    first = _answer(client, _request())
    assert _code(first) == 1 and first["error_code"]["message"] == ""
    assert first["trajcache"]["source"] == "planner" and first["group_name"] == "arm"
    assert first["trajectory_start"]["joint_state"] == {
        "name": ["shoulder", "elbow"],
        "position": START,
    }
    trajectory = first["trajectory"]
    assert trajectory["joint_trajectory"]["joint_names"] == ["shoulder", "elbow"]
    assert trajectory["multi_dof_joint_trajectory"] == {"joint_names": [], "points": []}
    times, positions, velocities = _points(first)
    assert len(times) > 2 and times[0] == 0 and np.all(np.diff(times) > 0)
    np.testing.assert_allclose(positions[[0, -1]], [START, GOAL], atol=1e-9)
    np.testing.assert_allclose(velocities[[0, -1]], 0.0, atol=1e-9)
    assert first["planning_time"] > 0

    second = _answer(client, _request())
    assert _code(second) == 1
    assert second["trajcache"]["source"] == "cache"
    assert second["trajcache"]["trajectory_id"] == first["trajcache"]["trajectory_id"]
    events = client.get("/v1/plan-events").json()["items"]
    assert sorted(e["source"] for e in events) == ["cache", "planner"]


def test_planner_timeout_is_timed_out(client_factory: ClientFactory) -> None:
    client = client_factory(worker_processes=1)
    model_id = register(client)["model_id"]
    assert client.put("/v1/robots/robot-1", json={"model_id": model_id}).status_code == 201
    assert client.put("/v1/robots/robot-1/scene", json=WALL_SCENE).status_code == 200
    answer = _answer(client, _request(goal=[1.0, 0.0], allowed_planning_time=0.5))
    assert _code(answer) == -6, answer["error_code"]
    assert answer["trajcache"]["status"] == "failure"
    assert answer["trajectory"]["joint_trajectory"]["points"] == []


def test_start_or_goal_in_collision(app_client: TestClient, robot_id: str) -> None:
    scene = {"objects": [BLOCKER]}
    assert app_client.put("/v1/robots/robot-1/scene", json=scene).status_code == 200
    start_hit = _answer(app_client, _request(start=[0.0, 0.0], goal=[1.0, 0.0]))
    assert _code(start_hit) == -10 and "blocker" in start_hit["error_code"]["message"]
    assert start_hit["trajcache"]["status"] == "invalid"
    assert start_hit["trajectory"]["joint_trajectory"]["points"] == []
    goal_hit = _answer(app_client, _request(start=[1.0, 0.0], goal=[0.0, 0.0]))
    assert _code(goal_hit) == -12 and "blocker" in goal_hit["error_code"]["message"]
    assert goal_hit["trajectory_start"]["joint_state"]["position"] == [1.0, 0.0]


@pytest.mark.parametrize(
    ("goals", "needle"),
    [
        ([{"position_constraints": [{"link_name": "fore"}]}], "constraint_region"),
        (
            [
                {
                    "joint_constraints": _joints(["shoulder", "elbow"], GOAL),
                    "orientation_constraints": [{"link_name": "fore"}],
                }
            ],
            "orientation_constraints",
        ),
        ([{"joint_constraints": _joints(["shoulder"], [1.0])}], "lacks elbow"),
        ([], "empty"),
        (
            [
                {
                    "joint_constraints": [
                        {"joint_name": "shoulder", "position": 1.0, "tolerance_below": -0.1},
                        {"joint_name": "elbow", "position": 0.5},
                    ]
                }
            ],
            "negative tolerance",
        ),
        ([{"joint_constraints": _joints(["shoulder", "elbow"], [1.0, 1.7])}], "elbow"),
    ],
    ids=["position-only", "mixed", "partial", "none", "negative-tolerance", "out-of-limits"],
)
def test_unusable_goals_are_invalid_goal_constraints(
    app_client: TestClient, robot_id: str, goals: list[dict[str, Any]], needle: str
) -> None:
    body = {**_request(), "goal_constraints": goals}
    answer = _answer(app_client, body)
    assert _code(answer) == -16, answer["error_code"]  # MoveItErrorCodes.INVALID_GOAL_CONSTRAINTS
    assert needle in answer["error_code"]["message"]
    assert answer["trajcache"]["status"] == "invalid"


@pytest.mark.parametrize(
    ("joint_state", "needle"),
    [
        ({"name": ["shoulder", "elbow", "wrist"], "position": [0, 0, 0]}, "'wrist'"),
        ({"name": ["shoulder"], "position": [0.0]}, "lacks elbow"),
        ({"name": ["shoulder", "elbow"], "position": [0.0, 1.7]}, "out of joint limits"),
    ],
    ids=["unknown-joint", "missing-joint", "out-of-limits"],
)
def test_unusable_start_states_are_invalid_robot_state(
    app_client: TestClient, robot_id: str, joint_state: dict[str, Any], needle: str
) -> None:
    body = {**_request(), "start_state": {"joint_state": joint_state}}
    answer = _answer(app_client, body)
    assert _code(answer) == -17, answer["error_code"]  # MoveItErrorCodes.INVALID_ROBOT_STATE
    assert needle in answer["error_code"]["message"]
    assert answer["trajectory_start"]["joint_state"] == joint_state  # echoed as sent


def test_scaling_factors_slow_the_answer(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    _store(app_client, model_id, [START, GOAL])
    full = _answer(app_client, _request(max_velocity_scaling_factor=1.0))
    default = _answer(app_client, _request())  # 0 or absent: 1, as in MoveIt
    half = _answer(
        app_client, _request(max_velocity_scaling_factor=0.5, max_acceleration_scaling_factor=0.5)
    )
    assert {a["trajcache"]["source"] for a in (full, default, half)} == {"cache"}
    t_full, _, v_full = _points(full)
    t_half, q_half, v_half = _points(half)
    assert t_full[-1] == pytest.approx(_points(default)[0][-1])
    assert t_half[-1] > 1.5 * t_full[-1]
    assert np.abs(v_full).max() > 0.6  # the URDF allows 1 rad/s
    assert np.abs(v_half).max() <= 0.5 + 1e-6
    np.testing.assert_allclose(q_half[-1], GOAL, atol=1e-9)


def test_json_bodies_bare_or_wrapped(app_client: TestClient, model_id: str, robot_id: str) -> None:
    _store(app_client, model_id, [START, GOAL])
    for body in (
        _request(planner_id="RRTConnectkConfigDefault", pipeline_id="ompl"),
        {"motion_plan_request": _request(planner_id="geometric::BITstar")},
        {"request": _request(planner_id="prm")},
    ):
        reply = app_client.post("/v1/robots/robot-1/motion-plan", json=body)
        assert reply.status_code == 200, reply.text
        assert _code(reply.json()) == 1 and reply.json()["trajcache"]["source"] == "cache"


def test_planar_base_moves_in_the_multi_dof_trajectory(app_client: TestClient) -> None:
    model_id = register(app_client, base="planar")["model_id"]
    assert app_client.put("/v1/robots/base-1", json={"model_id": model_id}).status_code == 201
    start, goal = [1.0, 2.0, 0.5, 0.0, 0.0], [1.5, 2.2, 0.8, 1.0, 0.5]
    _store(app_client, model_id, [start, goal])
    quarter = {"x": 0.0, "y": 0.0, "z": math.sin(0.25), "w": math.cos(0.25)}
    body = {
        "start_state": {
            "joint_state": {"name": ["shoulder", "elbow"], "position": [0.0, 0.0]},
            "multi_dof_joint_state": {
                "joint_names": ["virtual_joint"],
                "transforms": [{"translation": {"x": 1.0, "y": 2.0}, "rotation": quarter}],
            },
        },
        "goal_constraints": [
            {
                "joint_constraints": [
                    *_joints(
                        ["virtual_joint/x", "virtual_joint/y", "virtual_joint/theta", "shoulder"],
                        [1.5, 2.2, 0.8, 1.0],
                    ),
                    {"joint_name": "elbow", "position": 0.5, "tolerance_above": 0.1},
                ]
            }
        ],
    }
    answer = _answer(app_client, body, robot="base-1")
    assert _code(answer) == 1 and answer["trajcache"]["source"] == "cache"
    assert answer["trajectory_start"]["multi_dof_joint_state"]["joint_names"] == ["virtual_joint"]
    arm = answer["trajectory"]["joint_trajectory"]
    base = answer["trajectory"]["multi_dof_joint_trajectory"]
    assert arm["joint_names"] == ["shoulder", "elbow"] and base["joint_names"] == ["virtual_joint"]
    assert len(arm["points"]) == len(base["points"]) > 2
    assert [p["time_from_start"] for p in arm["points"]] == [
        p["time_from_start"] for p in base["points"]
    ]
    for point, pose in ((base["points"][0], start), (base["points"][-1], goal)):
        transform = point["transforms"][0]
        x, y, theta = pose[:3]
        assert transform["translation"] == pytest.approx({"x": x, "y": y, "z": 0.0})
        half = theta / 2
        assert transform["rotation"] == pytest.approx(
            {"x": 0.0, "y": 0.0, "z": math.sin(half), "w": math.cos(half)}
        )
    np.testing.assert_allclose(arm["points"][-1]["positions"], goal[3:], atol=1e-9)

    # An arm-only goal leaves the base free: it stays where it starts.
    _store(app_client, model_id, [start, [*start[:3], *goal[3:]]])
    arm_only = {
        **body,
        "goal_constraints": [{"joint_constraints": _joints(["shoulder", "elbow"], goal[3:])}],
    }
    still = _answer(app_client, arm_only, robot="base-1")
    assert _code(still) == 1
    last = still["trajectory"]["multi_dof_joint_trajectory"]["points"][-1]["transforms"][0]
    assert last["translation"] == pytest.approx({"x": 1.0, "y": 2.0, "z": 0.0})


@pytest.mark.parametrize(
    ("body", "needles"),
    [
        ("start_state: [unclosed", ["invalid YAML", "line 1"]),
        ("- just\n- a list\n", ["body", "valid dictionary"]),
        (
            {**_request(), "start_state": {"joint_state": {"name": ["a"], "position": ["x"]}}},
            ["body.start_state.joint_state.position[0]"],
        ),
        (
            {**_request(), "start_state": {"joint_state": {"name": ["a", "b"], "position": [0]}}},
            ["2 names but 1 positions"],
        ),
        (
            {**_request(), "goal_constraint": []},
            ["unknown field 'goal_constraint' (did you mean 'goal_constraints'?)"],
        ),
        (
            {**_request(), "path_constraints": {"joint_constraints": _joints(["elbow"], [0])}},
            ["body.path_constraints", "not supported"],
        ),
        (
            {
                **_request(),
                "trajectory_constraints": {
                    "constraints": [{"name": "c", **{"joint_constraints": _joints(["elbow"], [0])}}]
                },
            },
            ["body.trajectory_constraints", "not supported"],
        ),
        (
            {**_request(), "start_state": {"attached_collision_objects": [{"link_name": "fore"}]}},
            ["attached_collision_objects", "not supported"],
        ),
        ({**_request(), "max_cartesian_speed": 0.2}, ["max_cartesian_speed", "not supported"]),
        ({**_request(), "pipeline_id": "pilz"}, ["pipeline_id", "ompl"]),
        ({**_request(), "max_velocity_scaling_factor": 1.5}, ["max_velocity_scaling_factor"]),
    ],
    ids=[
        "bad-yaml",
        "not-a-mapping",
        "not-a-number",
        "unpaired",
        "misspelt-field",
        "path-constraints",
        "trajectory-constraints",
        "attached-objects",
        "cartesian-speed",
        "other-pipeline",
        "scaling-above-1",
    ],
)
def test_malformed_or_unsupported_requests_are_422(
    app_client: TestClient, robot_id: str, body: dict[str, Any] | str, needles: list[str]
) -> None:
    assert_detail(_post(app_client, body), 422, *needles)


def test_bad_json_other_media_types_and_unknown_robots(
    app_client: TestClient, robot_id: str
) -> None:
    url = "/v1/robots/robot-1/motion-plan"
    headers = {"content-type": "application/json"}
    assert_detail(app_client.post(url, content="{", headers=headers), 422, "invalid JSON")
    csv = app_client.post(url, content="a,b", headers={"content-type": "text/csv"})
    assert_detail(csv, 415, "text/csv")
    assert_detail(app_client.post("/v1/robots/ghost/motion-plan", json=_request()), 404, "ghost")


def test_the_documented_yaml_example_succeeds(
    client_factory: ClientFactory, reference_urdf: str
) -> None:
    client = client_factory(worker_processes=1)
    model_id = register(client, reference_urdf, base="planar")["model_id"]
    assert client.put("/v1/robots/r1", json={"model_id": model_id}).status_code == 201
    text = (ROOT / "docs" / "moveit.md").read_text(encoding="utf-8")
    example = re.search(r"```yaml\n(.*?)```", text, re.DOTALL)
    assert example is not None
    answer = _answer(client, example.group(1), robot="r1")
    assert _code(answer) == 1, answer["error_code"]
    base = answer["trajectory"]["multi_dof_joint_trajectory"]
    assert base["joint_names"] == ["virtual_joint"]
    last = base["points"][-1]["transforms"][0]["translation"]  # the goal leaves the base free
    assert last == pytest.approx({"x": 1.375, "y": 1.3, "z": 0.0})
