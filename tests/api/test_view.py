"""The 3D view's endpoints: model files and render geometry, stored scene versions, paths as
link poses, and a plan event opened where its rejected candidate failed."""

from __future__ import annotations

import base64
import hashlib
import io
import math
import zipfile
from typing import Any

import numpy as np
import trimesh
from fastapi.testclient import TestClient
from scipy.spatial.transform import Rotation

from tests.api.conftest import ClientFactory, assert_detail, ctx_of, register
from tests.robots import TWO_JOINT_URDF
from tests.waiting import wait_until
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.validation.validator import Resolution, interpolate
from trajcache.reference.example_robots import ROBOTS
from trajcache.reference.robot import STOWED_ARM, reference_urdf
from trajcache.services.catalog.keys import create_key

DETOUR = [[0.0, 0.0], [-1.0, 0.0], [1.0, 0.0]]  # swings the shoulder back through -0.5 first


def _blocker(shoulder: float = -0.5, size: float = 0.04) -> dict[str, Any]:
    """A box in the sweep of the two-joint arm's upper link at `shoulder` (rad)."""
    position = [0.25 * math.sin(shoulder), 0.0, 0.1 + 0.25 * math.cos(shoulder)]
    return {"id": "blocker", "type": "box", "size": [size] * 3, "pose": {"position": position}}


def _ok(reply: Any, status: int = 200) -> Any:
    assert reply.status_code == status, reply.text
    return reply.json()


def _panda_archive() -> tuple[str, dict[str, bytes]]:
    files = ROBOTS["panda"].files()
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for path, data in files.items():
            archive.writestr(path, data)
    return base64.b64encode(buffer.getvalue()).decode(), files


def _pose_matrix(pose: list[float]) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = Rotation.from_quat(pose[3:7]).as_matrix()
    out[:3, 3] = pose[:3]
    return out


def test_the_reference_robot_is_drawn_from_its_primitives(app_client: TestClient) -> None:
    model_id = register(app_client, reference_urdf(), base="planar")["model_id"]
    view = _ok(app_client.get(f"/v1/view/models/{model_id}"))
    assert view["base"] == "planar" and view["state_names"][:3] == [
        "base_x",
        "base_y",
        "base_theta",
    ]
    kinds = {e["kind"] for e in view["elements"]}
    assert kinds <= {"box", "sphere", "cylinder", "capsule"} and "cylinder" in kinds
    assert all(e["mesh"] is None and len(e["origin"]) == 7 for e in view["elements"])
    names = view["link_names"]
    assert 0 <= view["end_effector_link"] < len(names)
    assert {names[e["link"]] for e in view["elements"]} >= {"base_link", "link7"}
    assert_detail(app_client.get("/v1/view/models/nope"), 404, "'nope' not found")
    assert_detail(app_client.get(f"/v1/view/models/{model_id}/meshes/0"), 404, "not a mesh")


def test_a_mesh_robot_s_meshes_are_its_checked_triangles_and_its_files_as_uploaded(
    app_client: TestClient,
) -> None:
    archive, files = _panda_archive()
    panda = ROBOTS["panda"]
    model_id = register(
        app_client, panda.urdf, srdf=panda.srdf, group="arm", archive_base64=archive
    )["model_id"]
    view = _ok(app_client.get(f"/v1/view/models/{model_id}"))
    meshes = [e for e in view["elements"] if e["kind"] == "mesh"]
    assert len(meshes) >= 8 and all(e["mesh"] and e["triangles"] > 0 for e in meshes)
    model = ctx_of(app_client).models.get(model_id)
    assert model is not None
    for element in meshes[:3]:
        reply = app_client.get(element["mesh"])
        assert reply.status_code == 200 and reply.headers["content-type"] == "model/stl"
        stl = trimesh.load(io.BytesIO(reply.content), file_type="stl", process=False)
        assert len(stl.faces) == element["triangles"]
        index = int(element["mesh"].rsplit("/", 1)[1])
        checked = model.elements[index].shape.vertices
        assert checked is not None
        np.testing.assert_allclose(
            stl.bounds, [checked.min(axis=0), checked.max(axis=0)], atol=1e-6
        )
    listed = _ok(app_client.get(f"/v1/robot-models/{model_id}"))["files"]
    path = listed[0]["path"]
    reply = app_client.get(f"/v1/robot-models/{model_id}/files/{path}")
    assert reply.status_code == 200 and reply.content == files[path]
    assert reply.headers["etag"] == f'"{hashlib.sha256(files[path]).hexdigest()}"'
    missing = app_client.get(f"/v1/robot-models/{model_id}/files/robots/none.stl")
    assert_detail(missing, 404, "has no file 'robots/none.stl'")
    assert_detail(app_client.get(f"/v1/view/models/{model_id}/meshes/9999"), 404, "no collision")


def test_scene_versions_by_robot_and_by_hash(app_client: TestClient, model_id: str) -> None:
    _ok(app_client.put("/v1/robots/r1", json={"model_id": model_id}), 201)
    first = _ok(app_client.put("/v1/robots/r1/scene", json={"objects": [_blocker()]}))
    second = _ok(app_client.put("/v1/robots/r1/scene", json={"objects": [], "env": {"door": 0.5}}))
    one = _ok(app_client.get("/v1/robots/r1/scenes/1"))
    assert (one["robot_id"], one["version"], one["hash"]) == ("r1", 1, first["hash"])
    assert [o["id"] for o in one["objects"]] == ["blocker"] and one["created_at"]
    two = _ok(app_client.get(f"/v1/scenes/{second['hash']}"))
    assert (two["version"], two["env"], two["objects"]) == (2, {"door": 0.5}, [])
    assert_detail(app_client.get("/v1/robots/r1/scenes/3"), 404, "no scene version 3")
    assert_detail(app_client.get("/v1/robots/r9/scenes/1"), 404, "robot 'r9' not found")
    assert_detail(app_client.get("/v1/scenes/" + "0" * 64), 404, "no stored scene")
    assert_detail(app_client.get("/v1/scenes/xyz"), 422, "path.scene_hash")
    assert app_client.get("/v1/robots/r1/scenes/0").status_code == 422


def test_a_trajectory_is_posed_along_its_validation_samples_in_its_scene(
    app_client: TestClient,
) -> None:
    model_id = register(app_client, reference_urdf(), base="planar")["model_id"]
    _ok(app_client.put("/v1/robots/r1", json={"model_id": model_id}), 201)
    wall = {"id": "wall", "type": "box", "size": [0.1, 4, 2], "pose": {"position": [3, 0, 1]}}
    scene = _ok(app_client.put("/v1/robots/r1/scene", json={"objects": [wall]}))
    start = [0.0, 0.0, 0.0, *STOWED_ARM]
    goal = [1.0, 0.5, 1.2, *STOWED_ARM]
    goal[4] += 0.3
    body = {"model_id": model_id, "states": [start, goal], "scene_hash": scene["hash"]}
    trajectory_id = _ok(app_client.post("/v1/trajectories", json=body), 201)["trajectory_id"]
    view = _ok(app_client.get(f"/v1/view/trajectories/{trajectory_id}"))
    assert view["scene_hash"] == scene["hash"] and view["scene"]["objects"][0]["id"] == "wall"
    model = ctx_of(app_client).models.get(model_id)
    assert model is not None
    samples = interpolate(np.array([start, goal]), model, Resolution())
    frames = view["frames"]
    assert frames["count"] == frames["samples"] == len(samples) and frames["key"] == [
        0,
        len(samples) - 1,
    ]
    assert frames["sample"] == list(range(len(samples))) and view["failure"] is None
    links = frames["links"]
    assert 0 in links  # the base moves: its link is posed
    for k in (0, len(samples) // 2, len(samples) - 1):
        truth = link_transforms(model, samples[k])[0]
        for j, link in enumerate(links):
            pose = _pose_matrix(frames["poses"][k][7 * j : 7 * j + 7])
            np.testing.assert_allclose(pose, truth[link], atol=2e-6)
    other = _ok(app_client.put("/v1/robots/r1/scene", json={"objects": []}))
    shown = _ok(app_client.get(f"/v1/view/trajectories/{trajectory_id}",
                               params={"scene_hash": other["hash"]}))  # fmt: skip
    assert shown["scene"]["objects"] == [] and shown["scene_hash"] == other["hash"]
    assert_detail(app_client.get("/v1/view/trajectories/999"), 404, "trajectory 999")


def test_a_rejected_candidate_s_event_opens_at_its_first_failing_sample(
    app_client: TestClient, model_id: str
) -> None:
    _ok(app_client.put("/v1/robots/r1", json={"model_id": model_id}), 201)
    _ok(app_client.put("/v1/robots/r1/scene", json={"objects": [_blocker()]}))
    stored = _ok(
        app_client.post("/v1/trajectories", json={"model_id": model_id, "states": DETOUR}), 201
    )
    body = {"start": [0.02, 0.0], "goal": [0.98, 0.0], "options": {"fallback": False}}
    answer = _ok(app_client.post("/v1/robots/r1/plan", json=body))
    assert answer["status"] == "miss"
    [event] = _ok(app_client.get("/v1/plan-events", params={"robot_id": "r1"}))["items"]
    [rejection] = event["rejections"]
    assert rejection["trajectory_id"] == stored["trajectory_id"]
    assert rejection["pairs"] == [{"link": "upper", "other": "blocker", "kind": "scene"}]
    assert 0 < rejection["sample"] < rejection["samples"] and rejection["state"][0] < -0.2

    view = _ok(app_client.get(f"/v1/view/plan-events/{event['event_id']}"))
    assert (
        view["event"]["event_id"] == event["event_id"] and view["scene_hash"] == event["scene_hash"]
    )
    assert [o["id"] for o in view["scene"]["objects"]] == ["blocker"]
    key = np.array(DETOUR)
    key[0], key[-1] = [0.02, 0.0], [0.98, 0.0]  # the candidate as it was validated
    np.testing.assert_allclose(view["key_states"], key)
    failure = view["failure"]
    assert failure["candidate"] == 0 and failure["rejection"] == rejection
    assert failure["frame"] == rejection["sample"]  # frames are the validation samples
    assert len(failure["poses"]) == 7 * len(view["frames"]["links"])
    assert_detail(
        app_client.get(f"/v1/view/plan-events/{event['event_id']}", params={"candidate": 1}),
        404,
        "no rejected candidate 1",
    )
    assert_detail(app_client.get("/v1/view/plan-events/999"), 404, "plan event 999")


def test_the_view_is_for_admin_keys_only(client_factory: ClientFactory) -> None:
    client = client_factory(auth_mode="on", auth_cache_ttl_s=0)
    ctx = ctx_of(client)
    secrets = {}
    with ctx.sessions() as session:
        for role in ("admin", "seeder", "robot"):
            robots = ["r1"] if role == "robot" else None
            secrets[role] = create_key(session=session, name=role, role=role, robot_ids=robots)[1]
    admin = {"Authorization": f"Bearer {secrets['admin']}"}
    registered = client.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF}, headers=admin)
    model_id = _ok(registered, 201)["model_id"]
    _ok(client.put("/v1/robots/r1", json={"model_id": model_id}, headers=admin), 201)
    scene = _ok(client.put("/v1/robots/r1/scene", json={"objects": [_blocker()]}, headers=admin))
    paths = [
        f"/v1/view/models/{model_id}",
        f"/v1/view/models/{model_id}/meshes/0",
        f"/v1/robot-models/{model_id}/files/a.stl",
        "/v1/robots/r1/scenes/1",
        f"/v1/scenes/{scene['hash']}",
        "/v1/view/trajectories/1",
        "/v1/view/plan-events/1",
    ]
    for path in paths:
        for role in ("seeder", "robot"):  # the robot key is bound to r1, and still refused
            headers = {"Authorization": f"Bearer {secrets[role]}"}
            assert_detail(client.get(path, headers=headers), 403, "admin only")
        assert client.get(path, headers=admin).status_code in (200, 404), path
    assert client.get("/v1/robots/r1/scenes/1", headers=admin).status_code == 200


def test_an_event_without_rejections_shows_its_trajectory(
    app_client: TestClient, model_id: str
) -> None:
    _ok(app_client.put("/v1/robots/r1", json={"model_id": model_id}), 201)
    path = [[0.0, 0.0], [0.5, 0.2], [1.0, 0.0]]
    stored = _ok(
        app_client.post("/v1/trajectories", json={"model_id": model_id, "states": path}), 201
    )
    body = {"start": [0.01, 0.0], "goal": [0.99, 0.0], "options": {"fallback": False}}
    assert _ok(app_client.post("/v1/robots/r1/plan", json=body))["source"] == "cache"
    [event] = _ok(app_client.get("/v1/plan-events"))["items"]
    assert event["rejections"] == []
    view = _ok(app_client.get(f"/v1/view/plan-events/{event['event_id']}"))
    assert view["trajectory_id"] == stored["trajectory_id"] and view["failure"] is None
    np.testing.assert_allclose(view["key_states"], path)
    assert view["notes"] and "stored path" in view["notes"][0]


def test_a_rejected_candidate_is_posed_with_the_joint_values_held_when_it_was_validated(
    app_client: TestClient,
) -> None:
    registered = app_client.post(
        "/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "joint_names": ["shoulder"]}
    )
    model_id = _ok(registered, 201)["model_id"]  # the elbow is held, not planned
    robot = {"model_id": model_id, "joint_values": {"elbow": 0.5}}
    _ok(app_client.put("/v1/robots/r1", json=robot), 201)
    _ok(app_client.put("/v1/robots/r1/scene", json={"objects": [_blocker()]}))
    detour = [[0.0], [-1.0], [1.0]]
    _ok(app_client.post("/v1/trajectories", json={"model_id": model_id, "states": detour}), 201)
    body = {"start": [0.02], "goal": [0.98], "options": {"fallback": False}}
    assert _ok(app_client.post("/v1/robots/r1/plan", json=body))["status"] == "miss"
    [event] = _ok(app_client.get("/v1/plan-events", params={"robot_id": "r1"}))["items"]
    [rejection] = event["rejections"]
    assert rejection["held"] == {"elbow": 0.5}
    url = f"/v1/view/plan-events/{event['event_id']}"
    before = _ok(app_client.get(url))
    _ok(app_client.put("/v1/robots/r1", json={**robot, "joint_values": {"elbow": 1.2}}))
    after = _ok(app_client.get(url))
    # The forearm is where the elbow held it then, not where the robot holds it now.
    assert after["failure"]["poses"] == before["failure"]["poses"]
    assert after["frames"]["poses"] == before["frames"]["poses"]


def test_a_seed_job_s_scenes_are_kept_and_its_trajectories_shown_in_them(
    client_factory: ClientFactory,
) -> None:
    client = client_factory(worker_backend="none", seed_poll_interval_s=0.1)
    model_id = register(client)["model_id"]
    scene = {"objects": [_blocker()], "env": {"door": 0.25}}
    body = {"model_id": model_id, "scenes": [scene], "queries": [{"start": [0, 0], "goal": [1, 0]}]}
    job = _ok(client.post("/v1/seed-jobs", json=body), 202)
    events: list[Any] = []

    def planned() -> bool:
        ctx_of(client).records.flush()
        params = {"robot_id": f"seed-job-{job['job_id']}"}
        events[:] = _ok(client.get("/v1/plan-events", params=params))["items"]
        return bool(events)

    assert wait_until(planned, timeout_s=60), "the job planned nothing"
    scene_hash = events[0]["scene_hash"]
    kept = _ok(client.get(f"/v1/scenes/{scene_hash}"))
    assert (kept["seed_job_id"], kept["robot_id"], kept["version"]) == (job["job_id"], None, None)
    assert [o["id"] for o in kept["objects"]] == ["blocker"] and kept["env"] == {"door": 0.25}
    stored = {"model_id": model_id, "states": [[0, 0], [1, 0]], "scene_hash": scene_hash}
    trajectory_id = _ok(client.post("/v1/trajectories", json=stored), 201)["trajectory_id"]
    view = _ok(client.get(f"/v1/view/trajectories/{trajectory_id}"))
    assert view["scene"]["seed_job_id"] == job["job_id"] and view["notes"] == []
    stored_row = _ok(client.get(f"/v1/trajectories/{trajectory_id}"))
    assert stored_row["min_clearance"] is not None  # its clearance, measured in that scene
    # A robot's version with the same content is named first.
    _ok(client.put("/v1/robots/r1", json={"model_id": model_id}), 201)
    _ok(client.put("/v1/robots/r1/scene", json=scene))
    assert _ok(client.get(f"/v1/scenes/{scene_hash}"))["robot_id"] == "r1"
