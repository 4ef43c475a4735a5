"""The blocking client against the real app served by uvicorn on loopback (SQLite, PostgreSQL)."""

from __future__ import annotations

import hashlib
import io
import zipfile

import pytest
import trimesh
import yaml

import trajcache_client as tc
from tests.robots import MESH_URDF, PINCER_SRDF, PINCER_URDF, TWO_JOINT_URDF
from trajcache_client import Client

PATH = [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]
TABLE = {"id": "table", "type": "box", "size": [0.4, 0.4, 0.4], "pose": {"position": [2, 0, 0]}}
MOVEIT_YAML = """\
world:
  collision_objects:
    - id: shelf
      primitives: [{type: 1, dimensions: [0.3, 0.3, 0.3]}]
      primitive_poses: [{position: {x: -2.0, y: 0.0, z: 0.2}}]
"""


def _mesh_archive() -> tuple[bytes, bytes]:
    stl = bytes(trimesh.creation.box(extents=(0.1, 0.1, 0.2)).export(file_type="stl"))
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("meshes/part.stl", stl)
    return buffer.getvalue(), stl


def test_models_are_registered_once_and_read_back(client: Client) -> None:
    first = client.register_model(TWO_JOINT_URDF, name="two")
    again = client.register_model(TWO_JOINT_URDF, name="two")
    assert first.created and not again.created and again.model_id == first.model_id
    assert first.state_names == ["shoulder", "elbow"] and first.base == "fixed"

    archive, stl = _mesh_archive()
    meshy = client.register_model(MESH_URDF, base="planar", archive=archive)
    assert meshy.state_names == ["base_x", "base_y", "base_theta", "lift"]

    page = client.list_models(limit=1)
    assert page.total == 2 and [m.model_id for m in page.items] == [first.model_id]
    detail = client.get_model(meshy.model_id)
    assert detail.link_names == ["base", "arm"] and detail.upper[-1] == 0.5
    assert detail.lower[0] is None  # the planar base is unbounded in x
    assert [(f.path, f.sha256) for f in detail.files] == [
        ("meshes/part.stl", hashlib.sha256(stl).hexdigest())
    ]


def test_a_model_registered_with_its_srdf_plans_to_a_named_state(client: Client) -> None:
    model = client.register_model(PINCER_URDF, srdf=PINCER_SRDF, group="arm", joint_values="open")
    assert model.state_names == ["shoulder", "elbow"] and model.held_joints == {"finger": 0.03}
    assert model.named_states == {"ready": [0.5, -0.4]}
    reasons = {pair.links: pair.reason for pair in model.skipped_pairs}
    assert reasons[("base", "fore")] == "srdf" and reasons[("base", "upper")] == "adjacent"

    # Multipart (with an archive): the SRDF goes as a file, joint_values as JSON text.
    archive, _ = _mesh_archive()
    again = client.register_model(
        PINCER_URDF, srdf=PINCER_SRDF, group="arm", joint_values={"finger": 0.03}, archive=archive
    )
    assert (again.model_id, again.created) == (model.model_id, False)  # the same held values
    ajar = client.register_model(
        PINCER_URDF,
        srdf=PINCER_SRDF,
        group="arm",
        joint_values={"finger": 0.02},
        archive=archive,
        acceleration_limits={"shoulder": 2.0},
        end_effector_link="fore",
    )
    assert ajar.created and ajar.model_id != model.model_id
    detail = client.get_model(ajar.model_id)
    assert detail.held_joints == {"finger": 0.02} and detail.named_states == model.named_states
    assert detail.skipped_pairs == model.skipped_pairs and detail.end_effector_link == "fore"
    assert detail.acceleration_limits is not None and detail.acceleration_limits[0] == 2.0

    robot = client.put_robot("pincer-1", model.model_id, kind="sim", joint_values={"finger": 0.01})
    assert robot.kind == "sim" and robot.joint_values == {"finger": 0.01}
    assert client.get_robot("pincer-1") == robot
    path = [[0.0, 0.0], [0.25, -0.2], [0.5, -0.4]]
    stored = client.store_trajectory(model.model_id, path, source="sim")
    answer = client.plan("pincer-1", {"shoulder": 0.0, "elbow": 0.0}, "ready", {"fallback": False})
    assert answer.ok and answer.trajectory_id == stored.trajectory_id
    assert answer.states is not None and answer.states[-1] == [0.5, -0.4]
    back = client.plan("pincer-1", "ready", [0.0, 0.0], {"fallback": False})
    assert back.ok and back.trajectory_id == stored.trajectory_id


def test_moveit_motion_plans_are_answered_from_the_cache(client: Client) -> None:
    model = client.register_model(PINCER_URDF, srdf=PINCER_SRDF, group="arm")
    client.put_robot("pincer-1", model.model_id)
    stored = client.store_trajectory(model.model_id, [[0.0, 0.0], [0.5, -0.4]])
    goal = [{"joint_name": "shoulder", "position": 0.5}, {"joint_name": "elbow", "position": -0.4}]
    request = {
        "group_name": "arm",
        "start_state": {"joint_state": {"name": ["shoulder", "elbow"], "position": [0.0, 0.0]}},
        "goal_constraints": [{"joint_constraints": goal}],
        "allowed_planning_time": 1.0,
    }
    for body in (request, yaml.safe_dump({"motion_plan_request": request})):
        answer = client.motion_plan("pincer-1", body)
        assert answer["error_code"]["val"] == 1, answer["error_code"]
        assert answer["trajcache"]["trajectory_id"] == stored.trajectory_id
        points = answer["trajectory"]["joint_trajectory"]["points"]
        assert points[-1]["positions"] == pytest.approx([0.5, -0.4])
    with pytest.raises(tc.ValidationError, match="path constraints"):
        client.motion_plan("pincer-1", {**request, "path_constraints": {"joint_constraints": goal}})


def test_a_scene_keeps_allowed_collisions_attached_objects_and_warns(client: Client) -> None:
    model = client.register_model(PINCER_URDF, srdf=PINCER_SRDF, group="arm")
    client.put_robot("pincer-1", model.model_id)
    bead = {
        "link": "fore",
        "object": {
            "id": "bead",
            "type": "sphere",
            "size": [0.015],
            "pose": {"position": [0, 0, 0.25]},
        },
        "touch_links": ["finger"],
    }
    native = {
        "objects": [TABLE],
        "allowed_collisions": [["finger", "table"]],
        "attached_objects": [bead],
    }
    assert client.put_scene("pincer-1", native).warnings == []
    scene = client.get_scene("pincer-1")
    assert scene.allowed_collisions == [["finger", "table"]]
    assert [a["object"]["id"] for a in scene.attached_objects] == ["bead"]

    moveit = {
        "world": {"collision_objects": []},
        "robot_state": {"joint_state": {"name": ["shoulder"], "position": [0.3]}},
    }
    warned = client.put_scene("pincer-1", moveit)
    assert any("robot_state.joint_state" in w for w in warned.warnings)
    assert client.get_scene("pincer-1").attached_objects == []


def test_robots_and_scenes_follow_the_world(client: Client) -> None:
    model = client.register_model(TWO_JOINT_URDF)
    robot = client.put_robot("robot-1", model.model_id)
    assert robot.scene_version == 0 and client.get_robot("robot-1") == robot

    v1 = client.put_scene("robot-1", {"objects": [TABLE], "env": {"door": 0.0}})
    assert v1.version == 1 and client.put_scene("robot-1", {"objects": [TABLE]}).version == 2
    v3 = client.put_scene("robot-1", MOVEIT_YAML)
    assert [o["id"] for o in client.get_scene("robot-1").objects] == ["shelf"]

    moved = {**TABLE, "pose": {"position": [2.5, 0, 0]}}
    v4 = client.patch_scene("robot-1", upsert=[moved], remove=["shelf"], env={"door": 0.5})
    scene = client.get_scene("robot-1")
    assert (v3.version, v4.version) == (3, 4) and scene.hash == v4.hash
    assert [o["id"] for o in scene.objects] == ["table"] and scene.env == {"door": 0.5}
    assert scene.objects[0]["pose"]["position"] == [2.5, 0.0, 0.0]
    assert client.get_robot("robot-1").scene_version == 4


def test_trajectories_are_stored_listed_planned_with_and_deleted(client: Client) -> None:
    model = client.register_model(TWO_JOINT_URDF)
    client.put_robot("robot-1", model.model_id)
    stored = client.store_trajectory(model.model_id, PATH, source="sim", robot_id="robot-1")
    assert stored.created
    assert not client.store_trajectory(model.model_id, PATH, source="sim").created

    listed = client.list_trajectories(model_id=model.model_id, source="sim")
    assert [t.trajectory_id for t in listed.items] == [stored.trajectory_id]
    assert client.list_trajectories(source="real").total == 0

    answer = client.plan("robot-1", [0.05, 0.02], [0.98, -0.03], {"fallback": False})
    assert answer.ok and answer.source == "cache"
    assert answer.trajectory_id == stored.trajectory_id
    assert answer.states is not None and answer.states[0] == [0.05, 0.02]
    assert set(answer.timings_ms) >= {"lookup", "validate", "plan", "total"}
    assert answer.quality is not None and answer.quality.path_length > 0
    assert answer.joint_trajectory is None

    options = tc.PlanOptions(fallback=False, quality="full", timing=tc.TimingOptions(path="linear"))
    timed = client.plan("robot-1", [0.05, 0.02], [0.98, -0.03], options)
    assert timed.ok and timed.joint_trajectory is not None and timed.quality is not None
    points = timed.joint_trajectory.points
    assert points[0].positions == pytest.approx([0.05, 0.02]) and points[0].time_from_start == 0
    assert timed.joint_trajectory.duration_s == pytest.approx(points[-1].time_from_start)
    assert timed.quality.duration_s == pytest.approx(timed.joint_trajectory.duration_s)

    trajectory = client.get_trajectory(stored.trajectory_id)
    assert trajectory.states == PATH and trajectory.source == "sim"

    client.delete_trajectory(stored.trajectory_id)
    with pytest.raises(tc.NotFoundError, match=f"trajectory {stored.trajectory_id} not found"):
        client.get_trajectory(stored.trajectory_id)
    miss = client.plan("robot-1", [0.05, 0.02], [0.98, -0.03], {"fallback": False})
    assert miss.status == "miss" and not miss.ok and miss.states is None


def test_service_errors_arrive_as_exceptions_naming_the_problem(client: Client) -> None:
    model = client.register_model(TWO_JOINT_URDF)
    client.put_robot("robot-1", model.model_id)
    with pytest.raises(tc.NotFoundError, match="robot 'ghost' not found"):
        client.get_robot("ghost")
    with pytest.raises(tc.ValidationError, match="start has 1 values") as caught:
        client.plan("robot-1", [0.0], [1.0, 0.0])
    assert caught.value.status_code == 422
    with pytest.raises(tc.ValidationError, match=r"path\.trajectory_id") as invalid:
        client.get_trajectory(0)
    assert invalid.value.errors[0]["loc"] == ["path", "trajectory_id"]
    with pytest.raises(tc.UnsupportedMediaTypeError):
        client.put_scene("robot-1", b"\x89PNG", media_type="image/png")
    with pytest.raises(tc.ValidationError, match="object 'a'"):
        client.put_scene("robot-1", {"objects": [{"id": "a", "type": "box"}]})
    with pytest.raises(tc.PayloadTooLargeError, match="max_trajectory_states"):
        client.store_trajectory(model.model_id, [[0.0, 0.0]] * 5001)
    with pytest.raises(tc.ValidationError, match="less than or equal to 1000"):
        client.list_trajectories(limit=100_000)


def test_health_and_readiness(client: Client) -> None:
    assert client.health().status == "ok"
    assert client.ready().status == "ready"
