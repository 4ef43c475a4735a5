"""Real robot descriptions as `example-robot-data` ships them, through the REST API: URDF with
meshes, SRDF groups, states and collision matrices, mimic and held joints."""

from __future__ import annotations

import base64
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail, register
from trajcache.reference.example_robots import ROBOTS, ExampleRobot

PANDA_ARM = [f"panda_joint{k}" for k in range(1, 8)]
# All joints at 0 within the limits (joint 4 at its upper limit): the Panda's wrist is folded,
# with the hand and link7 inside link5.
FOLDED = [0.0, 0.0, 0.0, -0.0698, 0.0, 0.0, 0.0]
READY = [0.0, -0.785398, 0.0, -2.35619, 0.0, 1.5707, 0.785398]  # the SRDF's "default"


def _archive(robot: ExampleRobot) -> str:
    return base64.b64encode(robot.archive()).decode()


def _register(client: TestClient, robot: ExampleRobot, **fields: Any) -> dict[str, Any]:
    body: dict[str, Any] = {"base": robot.base, "archive_base64": _archive(robot)}
    if robot.srdf is not None:
        body["srdf"] = robot.srdf
    if robot.group is not None:
        body["group"] = robot.group
    if robot.joint_names is not None:
        body["joint_names"] = list(robot.joint_names)
    return register(client, robot.urdf, **{**body, **fields})


def _robot(client: TestClient, model_id: str, robot_id: str = "arm-1") -> str:
    response = client.put(f"/v1/robots/{robot_id}", json={"model_id": model_id})
    assert response.status_code in (200, 201), response.text
    return robot_id


def _plan(client: TestClient, robot_id: str, start: Any, goal: Any, **options: Any) -> Any:
    body = {"start": start, "goal": goal, "options": {"fallback": False, **options}}
    return client.post(f"/v1/robots/{robot_id}/plan", json=body)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_every_shipped_robot_registers_with_its_srdf(app_client: TestClient, name: str) -> None:
    robot = ROBOTS[name]
    body = _register(app_client, robot)
    assert body["created"] is True
    assert len(body["joint_names"]) >= 6
    reasons = {pair["reason"] for pair in body["skipped_pairs"]}
    assert "adjacent" in reasons
    if robot.srdf is not None and "disable_collisions" in robot.srdf:
        assert "srdf" in reasons
    if name == "z1":  # its SRDF chain starts at a link the URDF calls otherwise: reported
        assert body["warnings"] == [
            "SRDF group 'end_effector': chain 'base' → 'gripperMover' has an unknown link"
        ]
    detail = app_client.get(f"/v1/robot-models/{body['model_id']}").json()
    assert detail["skipped_pairs"] == body["skipped_pairs"]
    assert detail["held_joints"] == body["held_joints"]


def test_the_folded_panda_is_refused_without_an_srdf_and_accepted_with_it(
    app_client: TestClient,
) -> None:
    panda = ROBOTS["panda"]
    bare = register(app_client, panda.urdf, joint_names=PANDA_ARM, archive_base64=_archive(panda))
    skipped = {tuple(sorted(p["links"])) for p in bare["skipped_pairs"]}
    assert ("panda_hand", "panda_link5") not in skipped  # in contact at 0: still checked
    robot_id = _robot(app_client, bare["model_id"], "bare-panda")
    detail = assert_detail(_plan(app_client, robot_id, FOLDED, READY), 422, "start state")
    assert "panda_link5" in detail and ("panda_hand" in detail or "panda_link7" in detail)

    shipped = _register(app_client, panda)  # the SRDF allows link5–hand and link5–link7
    assert shipped["joint_names"] == PANDA_ARM
    reasons = {tuple(sorted(p["links"])): p["reason"] for p in shipped["skipped_pairs"]}
    assert reasons[("panda_hand", "panda_link5")] == "srdf"
    robot_id = _robot(app_client, shipped["model_id"], "panda")
    answer = _plan(app_client, robot_id, FOLDED, READY)
    assert answer.status_code == 200, answer.text


def test_states_by_name_and_named_states(app_client: TestClient) -> None:
    panda = ROBOTS["panda"]
    body = _register(app_client, panda)
    assert body["named_states"]["default"] == pytest.approx(READY)
    assert body["held_joints"] == {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
    robot_id = _robot(app_client, body["model_id"])
    start = dict(zip(PANDA_ARM, [0.3, -0.5, 0.0, -2.0, 0.0, 1.8, 0.6], strict=True))
    with_fingers = {**start, "panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
    answer = _plan(app_client, robot_id, with_fingers, "default")
    assert answer.status_code == 200, answer.text
    assert answer.json()["status"] == "miss"  # nothing cached, no fallback: but accepted
    opened = {**start, "panda_finger_joint1": 0.04}
    assert_detail(_plan(app_client, robot_id, opened, "default"), 422, "panda_finger_joint1")
    assert_detail(_plan(app_client, robot_id, start, "home"), 422, "unknown named state 'home'")
    del start["panda_joint3"]
    assert_detail(_plan(app_client, robot_id, start, "default"), 422, "lacks panda_joint3")


def test_held_joint_values_and_mimic_joints(app_client: TestClient) -> None:
    panda = ROBOTS["panda"]
    closed = _register(app_client, panda)
    opened = _register(app_client, panda, joint_values={"panda_finger_joint1": 0.035})
    assert opened["model_id"] != closed["model_id"]  # the held values are part of the id
    assert opened["held_joints"] == {"panda_finger_joint1": 0.035, "panda_finger_joint2": 0.035}
    by_state = _register(app_client, panda, joint_values="default")  # group_state "default"
    assert by_state["held_joints"]["panda_finger_joint2"] == pytest.approx(0.001)
    for values, needle in (
        ({"panda_finger_joint2": 0.01}, "mimics 'panda_finger_joint1'"),
        ({"panda_finger_joint1": 0.5}, "not in [0, 0.04]"),
        ({"panda_joint1": 0.1}, "is a planning joint"),
        ({"nope": 0.1}, "unknown joint 'nope'"),
    ):
        response = app_client.post(
            "/v1/robot-models",
            json={"urdf": panda.urdf, "srdf": panda.srdf, "group": "arm",
                  "archive_base64": _archive(panda), "joint_values": values},
        )  # fmt: skip
        assert_detail(response, 422, needle)


def test_the_mimic_finger_moves_with_its_leader() -> None:
    from trajcache.geometry.model.kinematics import link_transforms
    from trajcache.geometry.model.urdf import load_robot_model

    panda = ROBOTS["panda"]
    gaps = []
    for opening in (0.0, 0.03):
        model = load_robot_model(
            panda.urdf, files=panda.files(), srdf=panda.srdf, group="arm",
            joint_values={"panda_finger_joint1": opening},
        )  # fmt: skip
        links = link_transforms(model, READY)[0]
        left = links[model.link_names.index("panda_leftfinger"), :3, 3]
        right = links[model.link_names.index("panda_rightfinger"), :3, 3]
        gaps.append(float(np.linalg.norm(left - right)))
    assert gaps[1] - gaps[0] == pytest.approx(2 * 0.03, abs=1e-9)  # both fingers opened


def test_srdf_errors_are_named(app_client: TestClient) -> None:
    panda = ROBOTS["panda"]
    cases = (
        ({"srdf": "<robot><group name='a'>", "group": "a"}, "malformed SRDF"),
        ({"srdf": panda.srdf, "group": "legs"}, "no group 'legs'"),
        ({"group": "arm"}, "needs an SRDF"),
        ({"srdf": panda.srdf, "group": "arm", "joint_names": PANDA_ARM}, "not both"),
        ({"srdf": panda.srdf, "group": "arm", "joint_values": "tucked"}, "no group_state"),
    )
    for fields, needle in cases:
        response = app_client.post(
            "/v1/robot-models",
            json={"urdf": panda.urdf, "archive_base64": _archive(panda), **fields},
        )
        assert_detail(response, 422, needle)


def test_multipart_registration_takes_the_srdf_as_a_file(app_client: TestClient) -> None:
    panda = ROBOTS["panda"]
    assert panda.srdf is not None
    response = app_client.post(
        "/v1/robot-models",
        data={"group": "arm", "joint_values": '{"panda_finger_joint1": 0.02}'},
        files={
            "urdf": ("panda.urdf", panda.urdf.encode(), "application/xml"),
            "srdf": ("panda.srdf", panda.srdf.encode(), "application/xml"),
            "archive": ("meshes.zip", base64.b64decode(_archive(panda)), "application/zip"),
        },
    )
    assert response.status_code == 201, response.text
    assert response.json()["joint_names"] == PANDA_ARM
    assert response.json()["held_joints"]["panda_finger_joint2"] == 0.02


# --- the scene's collision matrix, attached objects and held joints --------------------------

SWING_START = [-0.6, *READY[1:]]  # joint 1 swings the hand from one side to the other
SWING_GOAL = [0.6, *READY[1:]]
OPEN = {"panda_finger_joint1": 0.04}
# The hand dips through READY and rises again in the arm's plane: the closed fingers stay clear
# of the plate beside them, the open left finger passes through it.
DIP = np.array([0.0, -0.15, 0.0, 0.0, 0.0, -0.3, 0.0])
DIP_START, DIP_GOAL = (np.array(READY) + DIP).tolist(), (np.array(READY) - DIP).tolist()


def _hand(link: str = "panda_hand") -> np.ndarray:
    from trajcache.geometry.model.kinematics import link_transforms
    from trajcache.geometry.model.urdf import load_robot_model

    panda = ROBOTS["panda"]
    model = load_robot_model(panda.urdf, files=panda.files(), srdf=panda.srdf, group="arm")
    return link_transforms(model, READY)[0][model.link_names.index(link)]


def _box(oid: str, centre: np.ndarray, size: float | list[float]) -> dict[str, Any]:
    sizes = [size] * 3 if isinstance(size, float) else size
    pose = {"position": [float(v) for v in centre], "orientation": [0, 0, 0, 1]}
    return {"id": oid, "type": "box", "size": sizes, "pose": pose}


def _plate() -> dict[str, Any]:
    """A small box 4 cm beside the left finger at READY: the open finger reaches into it."""
    hand, finger = _hand(), _hand("panda_leftfinger")
    centre = finger[:3, 3] + 0.04 * hand[:3, 1] + 0.03 * hand[:3, 2]
    return _box("plate", centre, [0.02, 0.01, 0.02])  # the hand's axes are the world's, flipped


def _store(client: TestClient, model_id: str, states: list[list[float]]) -> int:
    stored = client.post(
        "/v1/trajectories", json={"model_id": model_id, "states": states, "source": "sim"}
    )
    assert stored.status_code in (200, 201), stored.text
    return int(stored.json()["trajectory_id"])


def test_a_scene_matrix_entry_lets_a_link_touch_an_object(app_client: TestClient) -> None:
    model_id = _register(app_client, ROBOTS["panda"])["model_id"]
    robot_id = _robot(app_client, model_id)
    assert app_client.put(f"/v1/robots/{robot_id}", json={"model_id": model_id,
                          "joint_values": OPEN}).status_code == 200  # fmt: skip
    plate = _plate()
    position = dict(zip("xyz", plate["pose"]["position"], strict=True))
    world = {"collision_objects": [{
        "id": "plate", "header": {"frame_id": "world"},
        "primitives": [{"type": 1, "dimensions": plate["size"]}],
        "primitive_poses": [{"position": position, "orientation": [0, 0, 0, 1]}],
    }]}  # fmt: skip
    matrix = {
        "entry_names": ["panda_leftfinger", "plate"],
        "entry_values": [{"enabled": [False, True]}, {"enabled": [True, False]}],
    }
    allowed = app_client.put(
        f"/v1/robots/{robot_id}/scene",
        json={"world": world, "allowed_collision_matrix": matrix,
              "robot_state": {"joint_state": {"name": ["panda_joint1"], "position": [0.0]}}},
    )  # fmt: skip
    assert allowed.status_code == 200, allowed.text
    assert any("robot_state.joint_state" in w for w in allowed.json()["warnings"])
    assert app_client.get(f"/v1/robots/{robot_id}/scene").json()["allowed_collisions"] == [
        ["panda_leftfinger", "plate"]
    ]
    answer = _plan(app_client, robot_id, READY, SWING_GOAL)
    assert answer.status_code == 200, answer.text

    bare = app_client.put(f"/v1/robots/{robot_id}/scene", json={"world": world})
    assert bare.status_code == 200 and bare.json()["version"] == allowed.json()["version"] + 1
    assert_detail(
        _plan(app_client, robot_id, READY, SWING_GOAL),
        422,
        "start state is in collision: link 'panda_leftfinger' hits object 'plate'",
    )


def test_an_attached_object_blocks_a_path_the_bare_arm_could_take(app_client: TestClient) -> None:
    model_id = _register(app_client, ROBOTS["panda"])["model_id"]
    robot_id = _robot(app_client, model_id)
    hand = _hand()
    post = _box("post", hand[:3, 3] + 0.36 * hand[:3, 2], 0.06)  # below the fingertips
    trajectory_id = _store(app_client, model_id, [SWING_START, READY, SWING_GOAL])
    assert app_client.put(f"/v1/robots/{robot_id}/scene", json={"objects": [post]}).status_code in (
        200,
        201,
    )
    bare = _plan(app_client, robot_id, SWING_START, SWING_GOAL).json()
    assert (bare["status"], bare["trajectory_id"]) == ("success", trajectory_id)

    rod = {"link": "panda_hand", "touch_links": ["panda_leftfinger", "panda_rightfinger"],
           "object": {"id": "rod", "type": "cylinder", "size": [0.01, 0.3],
                      "pose": {"position": [0, 0, 0.25], "orientation": [0, 0, 0, 1]}}}  # fmt: skip
    held = app_client.put(
        f"/v1/robots/{robot_id}/scene", json={"objects": [post], "attached_objects": [rod]}
    )
    assert held.status_code == 200, held.text
    assert held.json()["warnings"] == []
    blocked = _plan(app_client, robot_id, SWING_START, SWING_GOAL).json()
    assert blocked["status"] == "miss"
    assert "link 'rod' hits object 'post'" in blocked["rejected"][0]["reason"]

    rod["link"] = "panda_wrist"
    assert_detail(
        app_client.put(
            f"/v1/robots/{robot_id}/scene", json={"objects": [post], "attached_objects": [rod]}
        ),
        422,
        "no link 'panda_wrist'",
    )


def test_a_path_cached_with_the_gripper_closed_is_validated_again_when_it_is_open(
    app_client: TestClient,
) -> None:
    model_id = _register(app_client, ROBOTS["panda"])["model_id"]
    trajectory_id = _store(app_client, model_id, [DIP_START, READY, DIP_GOAL])
    closed = _robot(app_client, model_id, "closed")
    opened = app_client.put("/v1/robots/opened", json={"model_id": model_id, "joint_values": OPEN})
    assert opened.status_code == 201, opened.text
    assert opened.json()["joint_values"] == OPEN
    for robot_id in (closed, "opened"):
        scene = app_client.put(f"/v1/robots/{robot_id}/scene", json={"objects": [_plate()]})
        assert scene.status_code in (200, 201), scene.text

    hit = _plan(app_client, closed, DIP_START, DIP_GOAL).json()
    assert (hit["status"], hit["trajectory_id"]) == ("success", trajectory_id)
    again = _plan(app_client, "opened", DIP_START, DIP_GOAL).json()  # same path, same scene
    assert again["status"] == "miss"
    assert "link 'panda_leftfinger' hits object 'plate'" in again["rejected"][0]["reason"]
    by_name = dict(zip(PANDA_ARM, DIP_START, strict=True))
    fingers = {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}  # the robot's own
    assert _plan(app_client, "opened", {**by_name, **fingers}, DIP_GOAL).status_code == 200
    closed_fingers = {**by_name, "panda_finger_joint1": 0.0}
    assert_detail(_plan(app_client, "opened", closed_fingers, DIP_GOAL), 422, "holds it at 0.04")

    reset = app_client.put("/v1/robots/opened", json={"model_id": model_id, "joint_values": {}})
    assert reset.json()["joint_values"] == {}
    assert _plan(app_client, "opened", DIP_START, DIP_GOAL).json()["status"] == "success"
    for values, needle in (
        ({"panda_finger_joint1": 0.5}, "not in [0, 0.04]"),
        ({"panda_joint1": 0.1}, "is a planning joint"),
        ({"panda_finger_joint2": 0.01}, "mimics"),
    ):
        response = app_client.put(
            "/v1/robots/opened", json={"model_id": model_id, "joint_values": values}
        )
        assert_detail(response, 422, needle)
