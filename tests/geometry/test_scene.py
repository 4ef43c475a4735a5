"""Native scene parsing, validation, canonical hashing, serialization and patching."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
import yaml

from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.shapes import ShapeKind
from trajcache.geometry.scene.parse import load_scene_text, parse_scene
from trajcache.geometry.scene.payload import apply_patch, scene_to_payload
from trajcache.geometry.scene.scene import matrix_to_quaternion

S2 = math.sqrt(0.5)


def _payload() -> dict[str, Any]:
    return {
        "objects": [
            {
                "id": "wall_n",
                "type": "box",
                "size": [6.0, 0.1, 2.5],
                "pose": {"position": [3.0, 4.05, 1.25], "orientation": [0, 0, S2, S2]},
            },
            {"id": "ball", "type": "sphere", "size": [0.2], "pose": {"position": [1, 1, 1]}},
            {
                "id": "bowl",
                "type": "cylinder",
                "size": [0.2, 0.4],
                "pose": {"position": [0.45, 3.55, 0.2]},
            },
            {"id": "pill", "type": "capsule", "size": [0.05, 0.3], "pose": {"position": [2, 2, 1]}},
            {
                "id": "tri",
                "type": "mesh",
                "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                "faces": [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]],
                "pose": {"position": [4, 1, 0]},
            },
        ],
        "env": {"stall_2_door": 0.52, "stall_1_door": 0.0},
    }


def test_parses_every_shape_kind_with_poses() -> None:
    scene = parse_scene(_payload())
    by_id = {o.id: o for o in scene.objects}
    assert [o.id for o in scene.objects] == ["wall_n", "ball", "bowl", "pill", "tri"]
    assert by_id["wall_n"].shape.kind is ShapeKind.BOX
    assert by_id["bowl"].shape.size == (0.2, 0.4)
    assert by_id["tri"].shape.faces is not None and by_id["tri"].shape.faces.shape == (4, 3)
    np.testing.assert_allclose(by_id["wall_n"].pose[:3, 0], [0.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(by_id["wall_n"].pose[:3, 3], [3.0, 4.05, 1.25])
    np.testing.assert_allclose(by_id["ball"].pose[:3, :3], np.eye(3))  # orientation optional
    assert scene.env == {"stall_2_door": 0.52, "stall_1_door": 0.0}
    assert len(scene.hash) == 64


def test_hash_ignores_order_and_form() -> None:
    payload = _payload()
    reordered = {"env": dict(reversed(payload["env"].items())), "objects": payload["objects"][::-1]}
    base = parse_scene(payload).hash
    assert parse_scene(reordered).hash == base
    assert parse_scene(load_scene_text(json.dumps(payload))).hash == base
    assert parse_scene(load_scene_text(yaml.safe_dump(payload))).hash == base
    flipped = json.loads(json.dumps(payload))  # q and -q are the same rotation
    flipped["objects"][0]["pose"]["orientation"] = [0, 0, -S2, -S2]
    assert parse_scene(flipped).hash == base


def test_hash_changes_with_content() -> None:
    base = parse_scene(_payload()).hash
    moved = _payload()
    moved["objects"][2]["pose"]["position"][0] += 0.001
    assert parse_scene(moved).hash != base
    env = _payload()
    env["env"]["stall_2_door"] = 0.53
    assert parse_scene(env).hash != base
    renamed = _payload()
    renamed["objects"][1]["id"] = "ball2"
    assert parse_scene(renamed).hash != base


def test_round_trip_through_payload() -> None:
    scene = parse_scene(_payload())
    again = parse_scene(json.loads(json.dumps(scene_to_payload(scene))))
    assert again.hash == scene.hash
    for a, b in zip(scene.objects, again.objects, strict=True):
        np.testing.assert_allclose(a.pose, b.pose, atol=1e-12)


def test_slightly_unnormalized_quaternion_is_normalized() -> None:
    payload = _payload()
    payload["objects"][0]["pose"]["orientation"] = [0, 0, 0.75, 0.75]  # norm 1.06
    scene = parse_scene(payload)
    assert scene.hash == parse_scene(_payload()).hash
    rotation = scene.objects[0].pose[:3, :3]
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)


@pytest.mark.parametrize(
    ("mutate", "needle"),
    [
        (lambda p: p["objects"][2]["pose"].update(position=[0, float("nan"), 0]), "bowl"),
        (lambda p: p["objects"][2]["pose"].update(position=[0, float("inf"), 0]), "finite"),
        (lambda p: p["objects"][0]["pose"].update(orientation=[0, 0, 0, 2]), "not a unit"),
        (lambda p: p["objects"][0]["pose"].update(orientation=[0, 0, 0, 0]), "zero quaternion"),
        (lambda p: p["objects"][1].update(id="wall_n"), "duplicate object id 'wall_n'"),
        (lambda p: p["objects"][1].update(type="cone"), "unknown type 'cone'"),
        (lambda p: p["objects"][2].update(size=[0.2, -0.4]), "size[1]"),
        (lambda p: p["objects"][2].update(size=[0.2, 0.0]), "bowl"),
        (lambda p: p["objects"][0].update(size=[1, 2]), "wall_n"),
        (lambda p: p["objects"][0].update(size=[1, "2", 3]), "size[1]"),
        (lambda p: p["objects"][0].update(colour="red"), "colour"),
        (lambda p: p["objects"][4].update(faces=[[0, 1, 9]]), "tri"),
        (lambda p: p["objects"][1].update(id=""), "objects[1]"),
        (lambda p: p["env"].update(stall_3_door=float("nan")), "stall_3_door"),
        (lambda p: p["env"].update({3: 1.0}), "env key"),
        (lambda p: p["env"].update(flag=True), "flag"),
        (lambda p: p["objects"][1]["pose"].update(position=[10**400, 0, 0]), "ball"),
        (lambda p: p.update(extra=1), "extra"),
    ],
)
def test_invalid_scenes_name_the_culprit(mutate: Any, needle: str) -> None:
    payload = _payload()
    mutate(payload)
    with pytest.raises(SceneError) as info:
        parse_scene(payload)
    assert needle in str(info.value)


def test_nan_message_names_object_and_field() -> None:
    payload = _payload()
    payload["objects"][0]["pose"]["orientation"] = [0, 0, float("nan"), 1]
    with pytest.raises(SceneError, match=r"'wall_n'.*orientation"):
        parse_scene(payload)


def test_text_parsing_rejects_yaml_aliases_and_garbage() -> None:
    bomb = "a: &a [1, 1, 1]\nb: &b [*a, *a, *a]\nobjects: [*b]\n"
    with pytest.raises(SceneError, match="alias"):
        parse_scene(load_scene_text(bomb))
    with pytest.raises(SceneError):
        parse_scene(load_scene_text("objects: [unclosed"))
    with pytest.raises(SceneError, match="mapping"):
        parse_scene(load_scene_text("[1, 2, 3]"))
    with pytest.raises(SceneError, match="finite"):
        parse_scene(load_scene_text('{"objects": [{"id": "a", "type": "sphere", "size": [NaN]}]}'))


def test_empty_scene_is_valid() -> None:
    assert parse_scene({}).objects == ()
    assert parse_scene({"objects": [], "env": {"x": 1}}).env == {"x": 1.0}


def test_patch_upsert_remove_and_env() -> None:
    scene = parse_scene(_payload())
    door = {"id": "bowl", "type": "cylinder", "size": [0.2, 0.4], "pose": {"position": [9, 9, 0.2]}}
    new = {"id": "dryer", "type": "box", "size": [0.2, 0.3, 0.3]}
    patched = apply_patch(
        scene,
        {
            "upsert": [door, new],
            "remove": ["ball"],
            "env": {"stall_2_door": 1.2, "stall_1_door": None, "stall_3_door": 0.1},
        },
    )
    ids = [o.id for o in patched.objects]
    assert ids == ["wall_n", "bowl", "pill", "tri", "dryer"]  # replaced ids keep their place
    np.testing.assert_allclose(patched.objects[1].pose[:3, 3], [9, 9, 0.2])
    assert patched.env == {"stall_2_door": 1.2, "stall_3_door": 0.1}
    assert patched.hash != scene.hash
    assert scene.objects[1].id == "ball"  # the original is untouched
    # the patched scene hashes like the same content sent whole
    assert parse_scene(scene_to_payload(patched)).hash == patched.hash


def test_patch_errors() -> None:
    scene = parse_scene(_payload())
    with pytest.raises(SceneError, match="'nope'"):
        apply_patch(scene, {"remove": ["nope"]})
    with pytest.raises(SceneError, match="'ball'"):
        ball = {"id": "ball", "type": "sphere", "size": [1]}
        apply_patch(scene, {"remove": ["ball"], "upsert": [ball]})
    with pytest.raises(SceneError, match="'x'"):
        apply_patch(scene, {"upsert": [{"id": "x", "type": "sphere", "size": [float("nan")]}]})
    with pytest.raises(SceneError, match="k"):
        apply_patch(scene, {"env": {"k": float("inf")}})
    with pytest.raises(SceneError, match="unknown patch"):
        apply_patch(scene, {"add": []})
    assert apply_patch(scene, {}).hash == scene.hash


def test_matrix_to_quaternion_round_trip() -> None:
    rng = np.random.default_rng(3)
    from trajcache.geometry.model.shapes import pose_matrix

    for _ in range(50):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        out = matrix_to_quaternion(pose_matrix([0, 0, 0], q))
        assert out[3] >= 0
        np.testing.assert_allclose(abs(float(out @ q)), 1.0, atol=1e-12)
