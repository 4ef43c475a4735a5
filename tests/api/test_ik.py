"""POST /v1/robots/{id}/ik through the real app, natively and as MoveIt's GetPositionIK; every
returned state's pose checked independently with yourdfpy (not Pinocchio)."""

from __future__ import annotations

import io
import math
import re
from typing import Any

import numpy as np
import pytest
import yaml
from fastapi.testclient import TestClient
from scipy.spatial.transform import Rotation
from yourdfpy import URDF
from yourdfpy.urdf import filename_handler_null

from tests.api.conftest import assert_detail, ctx_of, register
from trajcache.geometry.validation.validator import validator_for
from trajcache.reference.robot import ARM_JOINT_NAMES, STOWED_ARM, reference_urdf
from trajcache.services.catalog.robots import robot_scene
from trajcache.services.robot_model import robot_model

BASE = [0.5, -0.2, 0.4]
SEED = [*BASE, *STOWED_ARM]
GOAL_ARM = [0.4, -0.6, 0.2, 0.9, 0.1, 1.2, -0.3]  # a reachable tool pose, away from the base


@pytest.fixture(scope="module")
def reference() -> Any:
    text = re.sub(r"^\s*<\?xml[^>]*\?>", "", reference_urdf().strip()).encode()
    return URDF.load(
        io.BytesIO(text),
        build_scene_graph=True,
        load_meshes=False,
        filename_handler=filename_handler_null,
    )


def _tool_pose(reference: Any, state: list[float], link: str = "tool_tip") -> np.ndarray:
    """World pose of `link` at a state of the reference robot, by yourdfpy."""
    reference.update_cfg(dict(zip(ARM_JOINT_NAMES, state[3:], strict=True)))
    x, y, theta = state[:3]
    base = np.eye(4)
    base[:2, :2] = ((math.cos(theta), -math.sin(theta)), (math.sin(theta), math.cos(theta)))
    base[:2, 3] = (x, y)
    return np.asarray(base @ reference.get_transform(link, "base_link"))


def _goal(reference: Any) -> tuple[list[float], list[float]]:
    pose = _tool_pose(reference, [*BASE, *GOAL_ARM])
    return _listed(pose[:3, 3]), _listed(Rotation.from_matrix(pose[:3, :3]).as_quat())


def _listed(values: Any) -> list[float]:
    return [float(v) for v in values]


def _within(reference: Any, state: list[float], position: list[float], quat: list[float]) -> bool:
    pose = _tool_pose(reference, state)
    angle = (Rotation.from_matrix(pose[:3, :3]).inv() * Rotation.from_quat(quat)).magnitude()
    return bool(np.linalg.norm(pose[:3, 3] - position) <= 1e-3 and angle <= 1e-2)


@pytest.fixture
def robot(app_client: TestClient) -> str:
    model_id = register(app_client, reference_urdf(), base="planar")["model_id"]
    assert app_client.put("/v1/robots/mobile-1", json={"model_id": model_id}).status_code == 201
    return "mobile-1"


def _ik(client: TestClient, robot: str, **fields: Any) -> Any:
    return client.post(f"/v1/robots/{robot}/ik", json={"link": "tool_tip", "seed": SEED, **fields})


def _scene(client: TestClient, robot: str, *objects: dict[str, Any]) -> None:
    response = client.put(f"/v1/robots/{robot}/scene", json={"objects": list(objects)})
    assert response.status_code in (200, 201), response.text


def _ball(at: list[float], radius: float) -> dict[str, Any]:
    return {"id": "ball", "type": "sphere", "size": [radius], "pose": {"position": at}}


def test_a_reachable_pose_is_solved_within_tolerance(
    app_client: TestClient, robot: str, reference: Any
) -> None:
    position, quat = _goal(reference)
    response = _ik(app_client, robot, position=position, orientation=quat)
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["status"] == "success" and body["link"] == "tool_tip"
    assert body["state"][:3] == BASE  # the base stays unless it may move
    assert _within(reference, body["state"], position, quat)
    assert body["state_names"][:3] == ["base_x", "base_y", "base_theta"]


def test_an_unreachable_pose_is_a_failure_not_an_error(app_client: TestClient, robot: str) -> None:
    response = _ik(app_client, robot, position=[5.0, 5.0, 0.5], budget_s=0.05)
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["status"] == "not_found" and body["state"] is None
    assert "no state reaches the pose of 'tool_tip'" in body["message"]


def test_the_base_moves_when_allowed(app_client: TestClient, robot: str, reference: Any) -> None:
    far = [*BASE[:2], BASE[2] + 1.0]
    pose = _tool_pose(reference, [far[0] + 0.8, far[1] + 0.3, far[2], *GOAL_ARM])
    position, quat = _listed(pose[:3, 3]), _listed(Rotation.from_matrix(pose[:3, :3]).as_quat())
    body = _ik(app_client, robot, position=position, orientation=quat, move_base=True).json()
    assert body["status"] == "success", body
    assert _within(reference, body["state"], position, quat)


def test_avoid_collisions_steers_around_an_obstacle_at_the_solution(
    app_client: TestClient, robot: str, reference: Any
) -> None:
    position, quat = _goal(reference)
    first = _ik(app_client, robot, position=position, orientation=quat).json()["state"]
    elbow = _tool_pose(reference, first, "link4")[:3, 3]  # the elbow, far from the tool
    _scene(app_client, robot, _ball(_listed(elbow), 0.05))
    avoided = _ik(app_client, robot, position=position, orientation=quat).json()
    assert avoided["status"] == "success", avoided
    assert avoided["state"] != first and _within(reference, avoided["state"], position, quat)
    ctx = ctx_of(app_client)
    model = robot_model(ctx=ctx, robot_id=robot)
    with ctx.sessions() as session:
        scene = robot_scene(session=session, scenes=ctx.scenes, robot_id=robot).scene
    checker = validator_for(model, scene, ctx.settings, cache=ctx.validators).checker
    assert checker.state_contacts(np.array(avoided["state"])) == []
    assert checker.state_contacts(np.array(first)) != []
    ignored = _ik(app_client, robot, position=position, orientation=quat, avoid_collisions=False)
    assert ignored.json()["state"] == first


def test_a_pose_inside_an_obstacle_is_found_only_in_collision(
    app_client: TestClient, robot: str, reference: Any
) -> None:
    position, quat = _goal(reference)
    _scene(app_client, robot, _ball(position, 0.04))
    body = _ik(app_client, robot, position=position, orientation=quat, budget_s=0.05).json()
    assert body["status"] == "in_collision" and body["state"] is None
    assert body["rejected"] >= 1 and "in collision" in body["message"]


def test_malformed_input_is_a_422_naming_the_field(app_client: TestClient, robot: str) -> None:
    bad_link = _ik(app_client, robot, link="nozzle", position=[0.5, 0.0, 0.8])
    assert_detail(bad_link, 422, "link", "'nozzle'", "tool_tip")
    response = _ik(app_client, robot, position=[0.5, 0.0])
    assert response.status_code == 422 and "position" in response.text
    response = _ik(app_client, robot, position=[0.5, 0.0, 0.8], position_tolerance=0)
    assert response.status_code == 422 and "position_tolerance" in response.text
    zero = _ik(app_client, robot, position=[0.5, 0.0, 0.8], orientation=[0, 0, 0, 0])
    assert_detail(zero, 422, "orientation", "zero quaternion")
    beyond = [*BASE, 9.0, *STOWED_ARM[1:]]
    assert_detail(_ik(app_client, robot, position=[0.5, 0.0, 0.8], seed=beyond), 422, "seed")


def _moveit(position: list[float], quat: list[float], **fields: Any) -> dict[str, Any]:
    state = {
        "joint_state": {"name": list(ARM_JOINT_NAMES), "position": list(STOWED_ARM)},
        "multi_dof_joint_state": {
            "joint_names": ["virtual_joint"],
            "transforms": [
                {
                    "translation": [BASE[0], BASE[1], 0.0],
                    "rotation": [0.0, 0.0, math.sin(BASE[2] / 2), math.cos(BASE[2] / 2)],
                }
            ],
        },
    }
    request = {
        "group_name": "arm",
        "robot_state": state,
        "ik_link_name": "tool_tip",
        "pose_stamped": {
            "header": {"frame_id": "world"},
            "pose": {"position": position, "orientation": quat},
        },
        "timeout": {"sec": 0, "nanosec": 50_000_000},
        **fields,
    }
    return {"ik_request": request}


def test_moveit_form_solves_and_answers_in_moveit_shape(
    app_client: TestClient, robot: str, reference: Any
) -> None:
    position, quat = _goal(reference)
    response = app_client.post(f"/v1/robots/{robot}/ik", json=_moveit(position, quat))
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["error_code"]["val"] == 1
    solution = body["solution"]
    assert solution["joint_state"]["name"] == list(ARM_JOINT_NAMES)
    assert solution["multi_dof_joint_state"]["joint_names"] == ["virtual_joint"]
    translation = solution["multi_dof_joint_state"]["transforms"][0]["translation"]
    assert [translation["x"], translation["y"]] == pytest.approx(BASE[:2])
    state = [*BASE, *solution["joint_state"]["position"]]
    assert _within(reference, state, position, quat)
    assert any("group_name" in w for w in body["trajcache"]["warnings"])


def test_moveit_form_no_solution_is_no_ik_solution(
    app_client: TestClient, robot: str, reference: Any
) -> None:
    far = app_client.post(f"/v1/robots/{robot}/ik", json=_moveit([5.0, 5.0, 0.5], [0, 0, 0, 1]))
    assert far.status_code == 200 and far.json()["error_code"]["val"] == -31
    assert far.json()["solution"]["joint_state"]["name"] == []
    position, quat = _goal(reference)
    _scene(app_client, robot, _ball(position, 0.04))
    default = app_client.post(f"/v1/robots/{robot}/ik", json=_moveit(position, quat))
    assert default.json()["error_code"]["val"] == 1  # avoid_collisions is false by default
    avoiding = _moveit(position, quat, avoid_collisions=True)
    blocked = app_client.post(f"/v1/robots/{robot}/ik", json=avoiding)
    assert blocked.status_code == 200 and blocked.json()["error_code"]["val"] == -31
    assert blocked.json()["trajcache"]["status"] == "in_collision"


def test_moveit_form_as_yaml_and_its_422s(
    app_client: TestClient, robot: str, reference: Any
) -> None:
    position, quat = _goal(reference)
    text = yaml.safe_dump(_moveit(position, quat))
    response = app_client.post(
        f"/v1/robots/{robot}/ik", content=text, headers={"content-type": "application/yaml"}
    )
    assert response.status_code == 200 and response.json()["error_code"]["val"] == 1
    bad = app_client.post(
        f"/v1/robots/{robot}/ik", json=_moveit(position, quat, ik_link_name="nozzle")
    )
    assert_detail(bad, 422, "ik_request.ik_link_name", "'nozzle'")
    zero = app_client.post(f"/v1/robots/{robot}/ik", json=_moveit(position, [0.0, 0.0, 0.0, 0.0]))
    assert_detail(zero, 422, "ik_request.pose_stamped.pose.orientation", "zero quaternion")
    constrained = _moveit(position, quat, constraints={"joint_constraints": [{"joint_name": "a"}]})
    response = app_client.post(f"/v1/robots/{robot}/ik", json=constrained)
    assert response.status_code == 422 and "constraints" in response.text


def test_an_srdf_end_effector_names_its_parent_link(app_client: TestClient, reference: Any) -> None:
    srdf = '<robot name="xarm7-mobile"><end_effector name="nozzle" parent_link="tool_tip"/></robot>'
    model_id = register(app_client, reference_urdf(), base="planar", srdf=srdf)["model_id"]
    assert app_client.put("/v1/robots/mobile-2", json={"model_id": model_id}).status_code == 201
    position, quat = _goal(reference)
    body = _ik(app_client, "mobile-2", link="nozzle", position=position, orientation=quat).json()
    assert body["status"] == "success" and body["link"] == "tool_tip"
    assert _within(reference, body["state"], position, quat)


def test_moveit_form_with_avoid_collisions_steers_around_an_obstacle(
    app_client: TestClient, robot: str, reference: Any
) -> None:
    position, quat = _goal(reference)
    url = f"/v1/robots/{robot}/ik"
    first = app_client.post(url, json=_moveit(position, quat)).json()["solution"]
    state = [*BASE, *first["joint_state"]["position"]]
    _scene(app_client, robot, _ball(_listed(_tool_pose(reference, state, "link4")[:3, 3]), 0.05))
    ignored = app_client.post(url, json=_moveit(position, quat)).json()  # MoveIt's default: false
    assert ignored["solution"] == first
    avoiding = app_client.post(url, json=_moveit(position, quat, avoid_collisions=True)).json()
    assert avoiding["error_code"]["val"] == 1, avoiding
    moved = [*BASE, *avoiding["solution"]["joint_state"]["position"]]
    assert moved != state and _within(reference, moved, position, quat)
