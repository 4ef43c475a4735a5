"""MoveIt PlanningScene input: shape conventions, pose composition, operations and frames."""

from __future__ import annotations

import copy
import json
import math
from typing import Any

import numpy as np
import pytest
import yaml

from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.shapes import ShapeKind
from trajcache.geometry.scene.moveit import scene_to_moveit
from trajcache.geometry.scene.parse import load_scene_text, parse_scene
from trajcache.geometry.scene.payload import scene_to_payload

S2 = math.sqrt(0.5)


def _pose(xyz: list[float], q: list[float] | None = None) -> dict[str, Any]:
    x, y, z = xyz
    qx, qy, qz, qw = q or [0.0, 0.0, 0.0, 1.0]
    return {
        "position": {"x": x, "y": y, "z": z},
        "orientation": {"x": qx, "y": qy, "z": qz, "w": qw},
    }


def _world() -> dict[str, Any]:
    return {
        "name": "restroom",
        "is_diff": False,
        "robot_state": {"joint_state": {"name": [], "position": []}},
        "world": {
            "collision_objects": [
                {
                    "header": {"frame_id": "world"},
                    "id": "toilet",
                    # object pose: 90° about z, then primitives offset in the object frame
                    "pose": _pose([1.0, 2.0, 0.0], [0.0, 0.0, S2, S2]),
                    "primitives": [
                        {"type": 3, "dimensions": [0.4, 0.2]},  # CYLINDER [height, radius]
                        {"type": "box", "dimensions": [0.45, 0.18, 0.38]},
                        {"type": 2, "dimensions": [0.05]},
                    ],
                    "primitive_poses": [
                        _pose([0.0, 0.0, 0.2]),
                        _pose([0.3, 0.0, 0.6], [S2, 0.0, 0.0, S2]),  # 90° about x
                        _pose([0.0, 0.1, 0.0]),
                    ],
                    "operation": 0,
                },
                {
                    "header": {"frame_id": "map"},
                    "id": "tri",
                    "meshes": [
                        {
                            "triangles": [{"vertex_indices": [0, 1, 2]}],
                            "vertices": [
                                {"x": 0, "y": 0, "z": 0},
                                {"x": 1, "y": 0, "z": 0},
                                {"x": 0, "y": 1, "z": 0},
                            ],
                        }
                    ],
                    "mesh_poses": [_pose([0.0, 0.0, 1.0])],
                    "operation": "add",
                },
                {"id": "gone", "operation": 1},
            ]
        },
    }


def test_cylinder_dimensions_are_height_then_radius() -> None:
    scene = parse_scene(_world())
    cylinder = next(o for o in scene.objects if o.id == "toilet")
    assert cylinder.shape.kind is ShapeKind.CYLINDER
    assert cylinder.shape.size == (0.2, 0.4)  # Shape is (radius, length)


def test_multi_primitive_ids_and_pose_composition() -> None:
    scene = parse_scene(_world())
    by_id = {o.id: o for o in scene.objects}
    assert list(by_id) == ["toilet", "toilet#1", "toilet#2", "tri"]
    # the cylinder: object pose (yaw 90° at (1, 2, 0)) × primitive offset (0, 0, 0.2)
    np.testing.assert_allclose(by_id["toilet"].pose[:3, 3], [1.0, 2.0, 0.2], atol=1e-12)
    # the box: offset (0.3, 0, 0.6) in the object frame → (0, 0.3, 0.6) in the world
    box = by_id["toilet#1"].pose
    np.testing.assert_allclose(box[:3, 3], [1.0, 2.3, 0.6], atol=1e-12)
    # rotation Rz(90°)·Rx(90°): local x → world y, local y → world z, local z → world x
    np.testing.assert_allclose(box[:3, :3], [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-12)
    np.testing.assert_allclose(by_id["toilet#2"].pose[:3, 3], [0.9, 2.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(by_id["tri"].pose[:3, 3], [0.0, 0.0, 1.0])
    assert "gone" not in by_id  # REMOVE entries are skipped in a full scene


def test_accepted_wrappings_and_formats_agree() -> None:
    full = _world()
    expected = parse_scene(full).hash
    assert parse_scene({"world": full["world"]}).hash == expected
    assert parse_scene({"collision_objects": full["world"]["collision_objects"]}).hash == expected
    assert parse_scene(load_scene_text(json.dumps(full))).hash == expected
    assert parse_scene(load_scene_text(yaml.safe_dump(full))).hash == expected


def test_same_geometry_as_native_gives_same_hash() -> None:
    scene = parse_scene(_world())
    assert parse_scene(scene_to_payload(scene)).hash == scene.hash
    assert parse_scene(scene_to_moveit(scene)).hash == scene.hash


def test_zero_quaternion_means_identity_as_in_moveit() -> None:
    world = _world()
    obj = world["world"]["collision_objects"][0]
    obj["pose"]["orientation"] = {"x": 0, "y": 0, "z": 0, "w": 0}
    scene = parse_scene(world)
    np.testing.assert_allclose(scene.objects[0].pose[:3, :3], np.eye(3))


@pytest.mark.parametrize(
    ("mutate", "needle"),
    [
        (lambda o: o.update(header={"frame_id": "base_link"}), "frame_id"),
        (lambda o: o["primitives"][0].update(type=4), "cone"),
        (lambda o: o["primitives"][0].update(type=9), "primitive"),
        (lambda o: o["primitives"][0].update(dimensions=[0.4]), "dimensions"),
        (lambda o: o["primitives"][0].update(dimensions=[0.4, -0.2]), "size[0]"),
        (lambda o: o["primitive_poses"].pop(), "primitive_poses"),
        (lambda o: o["primitive_poses"][1]["position"].update(y=float("nan")), "position.y"),
        (lambda o: o["pose"].update(orientation={"x": 0, "y": 0, "z": 0, "w": 3}), "unit"),
        (lambda o: o.update(operation=3), "MOVE"),
        (lambda o: o.update(planes=[{"coef": [0, 0, 1, 0]}]), "planes"),
    ],
)
def test_invalid_objects_name_the_id(mutate: Any, needle: str) -> None:
    world = _world()
    mutate(world["world"]["collision_objects"][0])
    with pytest.raises(SceneError) as info:
        parse_scene(world)
    assert "'toilet'" in str(info.value)
    assert needle in str(info.value)


def test_duplicate_add_and_append() -> None:
    world = _world()
    objects = world["world"]["collision_objects"]
    objects.append(copy.deepcopy(objects[1]))
    with pytest.raises(SceneError, match="duplicate object id 'tri'"):
        parse_scene(world)
    objects[-1]["operation"] = 2  # APPEND adds shapes to the same object
    ids = [o.id for o in parse_scene(world).objects]
    assert ids == ["toilet", "toilet#1", "toilet#2", "tri", "tri#1"]


def test_moveit_writer_shape() -> None:
    scene = parse_scene(
        {"objects": [{"id": "pill", "type": "capsule", "size": [0.05, 0.3]}], "env": {"a": 1}}
    )
    msg = scene_to_moveit(scene)
    (obj,) = msg["world"]["collision_objects"]
    assert obj["header"]["frame_id"] == "world" and obj["operation"] == 0
    assert [p["type"] for p in obj["primitives"]] == [3, 2, 2]
    assert obj["primitives"][0]["dimensions"] == [0.3, 0.05]  # [height, radius]
    assert [p["position"]["z"] for p in obj["primitive_poses"]] == [0.0, -0.15, 0.15]
