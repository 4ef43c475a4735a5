"""PUT /v1/robots/{robot_id}/scene with objects in the robot's root frame, as MoveIt resolves it:
for a fixed base the root link (and every link fixed to it) is posed in the world; a planar
base's root moves, so such frames are refused. Other call sites still take world frames only."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail, register
from tests.robots import joint, link, two_joint_arm
from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.frames import root_frames
from trajcache.geometry.scene.parse import parse_scene

# The 2-joint arm with a plate fixed to its root link `base`, 0.5 m ahead and turned 90° about z.
MOUNTED = two_joint_arm(name="mounted").replace(
    "</robot>",
    link("plate") + joint("plate_joint", "fixed", "base", "plate", xyz=(0.5, 0, 0),
                          rpy=(0, 0, np.pi / 2)) + "</robot>",
)  # fmt: skip


def _box(frame: str, x: float, oid: str = "box", **fields: Any) -> dict[str, Any]:
    return {
        "id": oid,
        "header": {"frame_id": frame},
        "primitives": [{"type": "box", "dimensions": [0.1, 0.1, 0.1]}],
        "primitive_poses": [{"position": [x, 0.0, 1.0], "orientation": [0, 0, 0, 1]}],
        **fields,
    }


def _scene(*objects: dict[str, Any], **fields: Any) -> dict[str, Any]:
    return {"world": {"collision_objects": list(objects)}, **fields}


def _robot(client: TestClient, base: str = "fixed") -> str:
    model_id = register(client, MOUNTED, base=base)["model_id"]
    assert client.put(f"/v1/robots/r-{base}", json={"model_id": model_id}).status_code == 201
    return f"r-{base}"


def _positions(client: TestClient, robot: str) -> dict[str, list[float]]:
    scene = client.get(f"/v1/robots/{robot}/scene").json()
    return {o["id"]: o["pose"]["position"] for o in scene["objects"]}


def test_root_frames_of_a_fixed_base_and_of_a_planar_one() -> None:
    frames = root_frames(load_robot_model(MOUNTED))
    assert set(frames.poses) == {"base", "plate"} and not frames.moving
    np.testing.assert_allclose(frames.poses["base"], np.eye(4))
    np.testing.assert_allclose(frames.poses["plate"][:3, 3], [0.5, 0.0, 0.0])
    planar = root_frames(load_robot_model(MOUNTED, base="planar"))
    assert planar.moving == {"base", "plate"} and not planar.poses


def test_objects_in_the_root_frame_of_a_fixed_base_are_placed_in_the_world(
    app_client: TestClient,
) -> None:
    robot = _robot(app_client)
    body = _scene(_box("base", 1.0), _box("/plate", 0.2, "on-plate"), _box("world", 2.0, "w"))
    assert app_client.put(f"/v1/robots/{robot}/scene", json=body).status_code == 200
    positions = _positions(app_client, robot)
    np.testing.assert_allclose(positions["box"], [1.0, 0.0, 1.0])
    np.testing.assert_allclose(positions["on-plate"], [0.5, 0.2, 1.0], atol=1e-12)  # turned 90°
    np.testing.assert_allclose(positions["w"], [2.0, 0.0, 1.0])
    diff = _scene(_box("plate", 0.3, "added"), is_diff=True)
    assert app_client.put(f"/v1/robots/{robot}/scene", json=diff).status_code == 200
    np.testing.assert_allclose(_positions(app_client, robot)["added"], [0.5, 0.3, 1.0], atol=1e-12)


def test_moving_links_and_a_planar_base_root_are_refused(app_client: TestClient) -> None:
    fixed = _robot(app_client)
    moving = app_client.put(f"/v1/robots/{fixed}/scene", json=_scene(_box("upper", 1.0)))
    assert_detail(moving, 422, "'upper'", "not a world frame", "'base'", "'plate'")
    planar = _robot(app_client, "planar")
    refused = app_client.put(f"/v1/robots/{planar}/scene", json=_scene(_box("base", 1.0)))
    assert_detail(refused, 422, "'base'", "planar base", "moves")


def test_without_a_model_only_world_frames_are_taken() -> None:
    with pytest.raises(SceneError, match="not a world frame"):
        parse_scene(_scene(_box("base", 1.0)))
