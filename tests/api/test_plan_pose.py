"""Plans to a goal given as a link's pose, through the real app: the goal state is found by IK
on a miss and among the cached trajectories' ends on a repeat; every answered path's last
state is checked against the pose independently, with yourdfpy (not Pinocchio)."""

from __future__ import annotations

import io
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from scipy.spatial.transform import Rotation
from yourdfpy import URDF
from yourdfpy.urdf import filename_handler_null

from tests.api.conftest import assert_detail, register
from tests.robots import TWO_JOINT_URDF
from trajcache.services.plan import flow, pose_goal

START = [0.0, 0.0]
GOAL = [0.9, 0.3]  # the forearm's pose there is the target


@pytest.fixture(scope="module")
def arm() -> Any:
    return URDF.load(
        io.BytesIO(TWO_JOINT_URDF.encode()),
        build_scene_graph=True,
        load_meshes=False,
        filename_handler=filename_handler_null,
    )


def fore_pose(arm: Any, state: list[float]) -> np.ndarray:
    arm.update_cfg({"shoulder": state[0], "elbow": state[1]})
    return np.asarray(arm.get_transform("fore", "base"))


def target(arm: Any, state: list[float], **fields: Any) -> dict[str, Any]:
    pose = fore_pose(arm, state)
    quat = Rotation.from_matrix(pose[:3, :3]).as_quat()
    return {"link": "fore", "position": pose[:3, 3].tolist(), "orientation": quat.tolist(),
            "position_tolerance": 1e-3, "orientation_tolerance": 1e-2, **fields}  # fmt: skip


def within(arm: Any, state: list[float], goal: dict[str, Any]) -> bool:
    pose = fore_pose(arm, state)
    gap = np.linalg.norm(pose[:3, 3] - goal["position"])
    turn = Rotation.from_matrix(pose[:3, :3]).inv() * Rotation.from_quat(goal["orientation"])
    return bool(
        gap <= goal["position_tolerance"] and turn.magnitude() <= goal["orientation_tolerance"]
    )


@pytest.fixture
def robot(app_client: TestClient) -> TestClient:
    model_id = register(app_client)["model_id"]
    assert app_client.put("/v1/robots/r1", json={"model_id": model_id}).status_code == 201
    assert app_client.put("/v1/robots/r1/scene", json={"objects": []}).status_code == 200
    return app_client


def plan(client: TestClient, goal_pose: dict[str, Any], **options: Any) -> dict[str, Any]:
    body = {"start": START, "goal_pose": goal_pose, "options": options}
    reply = client.post("/v1/robots/r1/plan", json=body)
    assert reply.status_code == 200, reply.text
    return dict(reply.json())


def test_a_pose_goal_is_planned_then_found_in_the_cache(robot: TestClient, arm: Any) -> None:
    goal = target(arm, GOAL)
    first = plan(robot, goal, fallback=True)
    assert first["status"] == "success" and first["source"] == "planner"
    assert first["goal_found_by"] == "ik"
    assert first["states"][-1] == first["goal_state"]
    assert within(arm, first["states"][-1], goal)
    again = plan(robot, goal, fallback=False)  # the cached path's end reaches it as it is
    assert again["source"] == "cache" and again["goal_found_by"] == "cached"
    assert again["goal_state"] == first["goal_state"]
    assert within(arm, again["states"][-1], goal)


def test_a_posted_trajectory_is_found_by_the_pose_of_its_end(robot: TestClient, arm: Any) -> None:
    """Stored through POST /v1/trajectories: its end poses are indexed as it is stored."""
    model_id = robot.get("/v1/robots/r1").json()["model_id"]
    body = {"model_id": model_id, "states": [START, [0.5, 0.2], GOAL], "source": "real"}
    posted = robot.post("/v1/trajectories", json=body)
    assert posted.status_code == 201, posted.text
    answer = plan(robot, target(arm, GOAL), fallback=False)
    assert answer["source"] == "cache" and answer["goal_found_by"] == "cached"
    assert answer["trajectory_id"] == posted.json()["trajectory_id"]


def test_a_pose_near_a_cached_end_is_solved_from_it(robot: TestClient, arm: Any) -> None:
    """The second pose is the forearm's at a state 0.02 rad away: IK from the cached end finds
    a state next to it, within the lookup threshold, and the cache answers."""
    plan(robot, target(arm, GOAL), fallback=True)
    nearby = target(arm, [GOAL[0] + 0.02, GOAL[1] - 0.02])
    answer = plan(robot, nearby, fallback=False)
    assert answer["source"] == "cache" and answer["goal_found_by"] == "ik"
    assert within(arm, answer["states"][-1], nearby)


def test_a_pose_further_from_a_cached_end_is_still_served_from_it(
    robot: TestClient, arm: Any
) -> None:
    """The pose's state lies 0.5 rad from the cached end: beyond the request's threshold, within
    the pose goals' (`TRAJCACHE_POSE_GOAL_THRESHOLD`, 1 rad). IK from the cached end finds it,
    and the cached path, its last state replaced and certified, answers; a start as far from
    the cached one finds nothing."""
    plan(robot, target(arm, GOAL), fallback=True)
    further = target(arm, [GOAL[0] + 0.5, GOAL[1] - 0.3])
    answer = plan(robot, further, fallback=False)
    assert answer["source"] == "cache" and answer["goal_found_by"] == "ik"
    assert within(arm, answer["states"][-1], further)
    assert np.abs(np.subtract(answer["goal_state"], GOAL)).max() > 0.2
    body = {"start": [0.5, 0.0], "goal_pose": further, "options": {"fallback": False}}
    missed = robot.post("/v1/robots/r1/plan", json=body).json()
    assert missed["status"] != "success"


def test_the_paths_a_hit_can_take_need_no_end_pose_read(
    robot: TestClient, arm: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A hit takes a path with an end near the request's start: their other ends come from the
    replica's trajectory index, as they are or as IK seeds, without reading the end-pose index;
    from a start no cached path is near, the whole cache is searched."""
    plan(robot, target(arm, GOAL), fallback=True)
    reads: list[str] = []
    whole = pose_goal.pose_ends

    def counted(*args: Any, **kwargs: Any) -> Any:
        reads.append("pose_ends")
        return whole(*args, **kwargs)

    monkeypatch.setattr(pose_goal, "pose_ends", counted)
    again = plan(robot, target(arm, GOAL), fallback=False)
    assert again["source"] == "cache" and again["goal_found_by"] == "cached"
    nearby = target(arm, [GOAL[0] + 0.02, GOAL[1] - 0.02])
    answer = plan(robot, nearby, fallback=False)
    assert answer["source"] == "cache" and answer["goal_found_by"] == "ik"
    assert within(arm, answer["states"][-1], nearby) and reads == []
    body = {"start": [0.6, 0.0], "goal_pose": nearby, "options": {"fallback": False}}
    assert robot.post("/v1/robots/r1/plan", json=body).status_code == 200
    assert reads == ["pose_ends"]


def test_the_path_a_pose_goal_was_found_from_is_tried_first(
    robot: TestClient, arm: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The goal state is found from the cached end nearest the pose; that end's path is the
    first candidate, unranked, even where ranking would favour another (a real robot's path,
    its end further from the pose)."""
    first = plan(robot, target(arm, GOAL), fallback=True)
    model_id = robot.get("/v1/robots/r1").json()["model_id"]
    body = {"model_id": model_id, "states": [START, [0.5, 0.2], [1.2, 0.3]], "source": "real"}
    assert robot.post("/v1/trajectories", json=body).status_code == 201
    ranked: list[int] = []
    whole = flow._ranked

    def counted(*args: Any, **kwargs: Any) -> Any:
        ranked.append(1)
        return whole(*args, **kwargs)

    monkeypatch.setattr(flow, "_ranked", counted)
    answer = plan(robot, target(arm, [GOAL[0] + 0.02, GOAL[1]]), fallback=False)
    assert answer["source"] == "cache" and answer["goal_found_by"] == "ik"
    assert answer["trajectory_id"] == first["trajectory_id"] and ranked == []


def test_ik_starts_from_a_path_proved_in_the_scene_before_a_nearer_one(
    robot: TestClient, arm: Any
) -> None:
    """Of the few ends nearest the pose, one whose path this replica proved in the current
    scene seeds IK (and is the first candidate) before a nearer one never validated here."""
    first = plan(robot, target(arm, GOAL), fallback=True)
    assert plan(robot, target(arm, GOAL), fallback=False)["source"] == "cache"  # proved here
    model_id = robot.get("/v1/robots/r1").json()["model_id"]
    body = {"model_id": model_id, "states": [START, [0.5, 0.2], [GOAL[0] + 0.05, GOAL[1]]]}
    assert robot.post("/v1/trajectories", json=body).status_code == 201
    answer = plan(robot, target(arm, [GOAL[0] + 0.06, GOAL[1]]), fallback=False)
    assert answer["source"] == "cache" and answer["goal_found_by"] == "ik"
    assert answer["trajectory_id"] == first["trajectory_id"]


def test_the_newest_paths_near_the_start_are_the_ones_considered(
    robot: TestClient, arm: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where more paths share the start than a pose goal ranks, it considers the most
    recently stored (here one: the posted path, not the older planned one)."""
    plan(robot, target(arm, GOAL), fallback=True)
    model_id = robot.get("/v1/robots/r1").json()["model_id"]
    end = [GOAL[0] + 0.05, GOAL[1]]
    body = {"model_id": model_id, "states": [START, [0.5, 0.2], end]}
    posted = robot.post("/v1/trajectories", json=body)
    assert posted.status_code == 201
    monkeypatch.setattr(pose_goal, "NEAR_START_POOL", 1)
    ranked: list[np.ndarray] = []
    whole = pose_goal.meets_target

    def seen(checked: Any, goal: Any, states: np.ndarray) -> Any:
        ranked.append(states.copy())
        return whole(checked, goal, states)

    monkeypatch.setattr(pose_goal, "meets_target", seen)
    answer = plan(robot, target(arm, [GOAL[0] + 0.02, GOAL[1]]), fallback=False)
    assert answer["source"] == "cache"
    assert answer["trajectory_id"] == posted.json()["trajectory_id"]
    np.testing.assert_allclose(ranked[0], [end])


def test_an_unreachable_pose_is_a_failure_not_an_error(robot: TestClient) -> None:
    far = {"link": "fore", "position": [2.0, 0.0, 2.0], "orientation": [0, 0, 0, 1]}
    answer = plan(robot, far, fallback=True)
    assert answer["status"] == "failure" and answer["states"] is None
    assert "no goal state puts 'fore'" in answer["message"]


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ({"start": START}, "exactly one of goal"),
        ({"start": START, "goal": GOAL, "goal_pose": {"position": [0, 0, 1]}}, "exactly one"),
        ({"start": START, "goal_pose": {"link": "nope", "position": [0, 0, 1]}}, "'nope'"),
        ({"start": START, "goal_pose": {"position": [0, 0]}}, "goal_pose.position"),
    ],
)
def test_a_malformed_pose_goal_is_a_422(
    robot: TestClient, body: dict[str, Any], needle: str
) -> None:
    assert_detail(robot.post("/v1/robots/r1/plan", json=body), 422, needle)


def moveit_request(goal: dict[str, Any], **position: Any) -> dict[str, Any]:
    """A MotionPlanRequest whose goal is a position constraint (a sphere) and an orientation
    constraint on the forearm, as MoveIt's pose goals are sent."""
    sphere = {"type": 2, "dimensions": [goal["position_tolerance"]]}
    at = {"position": goal["position"], "orientation": [0, 0, 0, 1]}
    region = {"primitives": [sphere], "primitive_poses": [at]}
    return {
        "start_state": {"joint_state": {"name": ["shoulder", "elbow"], "position": START}},
        "goal_constraints": [
            {
                "position_constraints": [
                    {
                        "link_name": "fore",
                        "header": {"frame_id": "base"},
                        "constraint_region": region,
                        **position,
                    }
                ],
                "orientation_constraints": [
                    {
                        "link_name": "fore",
                        "orientation": goal["orientation"],
                        "absolute_x_axis_tolerance": 0.01,
                        "absolute_y_axis_tolerance": 0.01,
                        "absolute_z_axis_tolerance": 0.01,
                    }
                ],
            }
        ],
        "allowed_planning_time": 2.0,
    }


def test_moveit_pose_constraints_are_a_pose_goal(robot: TestClient, arm: Any) -> None:
    goal = target(arm, GOAL)
    reply = robot.post("/v1/robots/r1/motion-plan", json=moveit_request(goal))
    assert reply.status_code == 200, reply.text
    body = reply.json()
    assert body["error_code"]["val"] == 1, body
    points = body["trajectory"]["joint_trajectory"]["points"]
    names = body["trajectory"]["joint_trajectory"]["joint_names"]
    last = dict(zip(names, points[-1]["positions"], strict=True))
    assert within(arm, [last["shoulder"], last["elbow"]], goal)


def test_moveit_pose_goals_that_cannot_be_read_or_reached(robot: TestClient, arm: Any) -> None:
    far = {**target(arm, GOAL), "position": [2.0, 0.0, 2.0]}
    unreached = robot.post("/v1/robots/r1/motion-plan", json=moveit_request(far)).json()
    assert unreached["error_code"]["val"] == -31  # NO_IK_SOLUTION
    offset = moveit_request(target(arm, GOAL), target_point_offset=[0.0, 0.0, 0.1])
    refused = robot.post("/v1/robots/r1/motion-plan", json=offset)
    assert "target_point_offset" in refused.text


def test_events_and_statistics_tell_pose_goals_from_joint_goals(
    robot: TestClient, arm: Any
) -> None:
    plan(robot, target(arm, GOAL), fallback=True)
    joint = robot.post("/v1/robots/r1/plan", json={"start": START, "goal": GOAL})
    assert joint.status_code == 200, joint.text
    poses = robot.get("/v1/plan-events", params={"goal_kind": "pose"}).json()["items"]
    assert [e["goal_kind"] for e in poses] == ["pose"]
    events = robot.get("/v1/plan-events").json()["items"]
    assert [e["goal_kind"] for e in events] == ["joint", "pose"]  # newest first
    stats = robot.get("/v1/stats", params={"window": "1h"}).json()
    assert stats["goal_kinds"] == {"joint": 1, "pose": 1}
    assert_detail(robot.get("/v1/plan-events", params={"goal_kind": "cartesian"}), 422, "goal_kind")
