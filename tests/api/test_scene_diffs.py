"""PUT /v1/robots/{robot_id}/scene with a MoveIt PlanningScene marked `is_diff: true`: it changes
the current scene as MoveIt would, and is never taken as the whole scene."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail
from trajcache.geometry.errors import SceneError
from trajcache.geometry.scene.parse import parse_scene


def _pose(x: float, y: float = 0.0, z: float = 0.5) -> dict[str, Any]:
    return {"position": [x, y, z], "orientation": [0.0, 0.0, 0.0, 1.0]}


def _box(oid: str, x: float, operation: str | int = "ADD", **extra: Any) -> dict[str, Any]:
    return {
        "id": oid,
        "header": {"frame_id": "world"},
        "pose": _pose(x),
        "primitives": [{"type": "box", "dimensions": [0.1, 0.1, 0.1]}],
        "primitive_poses": [_pose(0.0, z=0.0)],
        "operation": operation,
        **extra,
    }


def _diff(*objects: dict[str, Any], **fields: Any) -> dict[str, Any]:
    return {"is_diff": True, "world": {"collision_objects": list(objects)}, **fields}


def _ids(client: TestClient, robot_id: str) -> list[str]:
    scene = client.get(f"/v1/robots/{robot_id}/scene").json()
    return sorted(o["id"] for o in scene["objects"])


def _start(client: TestClient, robot_id: str) -> str:
    """Three world objects, `b` of two shapes (`b`, `b#1`), one allowed pair."""
    whole = {
        "world": {
            "collision_objects": [
                _box("a", 1.0),
                {
                    **_box("b", 1.5),
                    "primitives": [{"type": 2, "dimensions": [0.05]}] * 2,
                    "primitive_poses": [_pose(0.0, z=0.0), _pose(0.2, z=0.0)],
                },
                _box("c", 2.0),
            ]
        },
        "allowed_collision_matrix": {
            "entry_names": ["fore", "a"],
            "entry_values": [[False, True], [True, False]],
        },
    }
    put = client.put(f"/v1/robots/{robot_id}/scene", json=whole)
    assert put.status_code == 200, put.text
    return str(put.json()["hash"])


def test_a_diff_adding_one_object_keeps_every_other(app_client: TestClient, robot_id: str) -> None:
    _start(app_client, robot_id)
    url = f"/v1/robots/{robot_id}/scene"
    before = app_client.get(url).json()
    put = app_client.put(url, json=_diff(_box("d", 2.5)))
    assert put.status_code == 200, put.text
    assert put.json()["version"] == 2
    after = app_client.get(url).json()
    assert sorted(o["id"] for o in after["objects"]) == ["a", "b", "b#1", "c", "d"]
    kept = {o["id"]: o for o in after["objects"]}
    for obj in before["objects"]:
        assert kept[obj["id"]] == obj  # every other object as it was
    assert after["allowed_collisions"] == before["allowed_collisions"] == [["a", "fore"]]


def test_a_diff_as_yaml_is_a_diff_too(app_client: TestClient, robot_id: str) -> None:
    import yaml

    _start(app_client, robot_id)
    text = yaml.safe_dump(_diff(_box("d", 2.5)))
    put = app_client.put(
        f"/v1/robots/{robot_id}/scene", content=text, headers={"content-type": "application/yaml"}
    )
    assert put.status_code == 200, put.text
    assert _ids(app_client, robot_id) == ["a", "b", "b#1", "c", "d"]


def test_remove_add_and_append_as_in_moveit(app_client: TestClient, robot_id: str) -> None:
    _start(app_client, robot_id)
    url = f"/v1/robots/{robot_id}/scene"
    removed = app_client.put(url, json=_diff({"id": "b", "operation": "REMOVE"}))
    assert removed.status_code == 200, removed.text
    assert _ids(app_client, robot_id) == ["a", "c"]

    moved = app_client.put(url, json=_diff(_box("a", 3.0)))  # ADD of an existing id replaces it
    assert moved.status_code == 200, moved.text
    a = next(o for o in app_client.get(url).json()["objects"] if o["id"] == "a")
    assert a["pose"]["position"][0] == 3.0

    appended = app_client.put(url, json=_diff(_box("c", 0.5, operation=2)))  # APPEND
    assert appended.status_code == 200, appended.text
    assert _ids(app_client, robot_id) == ["a", "c", "c#1"]

    missing = app_client.put(url, json=_diff({"id": "zz", "operation": 1}))
    assert missing.status_code == 200, missing.text
    assert any("'zz'" in w and "not in the scene" in w for w in missing.json()["warnings"])

    cleared = app_client.put(url, json=_diff({"id": "", "operation": "REMOVE"}))
    assert cleared.status_code == 200, cleared.text
    assert _ids(app_client, robot_id) == []


def test_move_is_refused_and_changes_nothing(app_client: TestClient, robot_id: str) -> None:
    start = _start(app_client, robot_id)
    url = f"/v1/robots/{robot_id}/scene"
    refused = app_client.put(url, json=_diff(_box("d", 2.5), _box("a", 3.0, operation="MOVE")))
    assert_detail(refused, 422, "'a'", "MOVE", "ADD")
    now = app_client.get(url).json()
    assert (now["version"], now["hash"]) == (1, start)  # transactional: not even `d` was added


def test_a_matrix_in_a_diff_replaces_the_allowed_pairs(
    app_client: TestClient, robot_id: str
) -> None:
    _start(app_client, robot_id)
    url = f"/v1/robots/{robot_id}/scene"
    matrix = {"entry_names": ["fore", "c"], "entry_values": [[False, True], [True, False]]}
    put = app_client.put(url, json=_diff(allowed_collision_matrix=matrix))
    assert put.status_code == 200, put.text
    assert app_client.get(url).json()["allowed_collisions"] == [["c", "fore"]]
    assert _ids(app_client, robot_id) == ["a", "b", "b#1", "c"]


def _held(oid: str, operation: str = "ADD", link: str = "fore") -> dict[str, Any]:
    obj = _box(oid, 0.0, operation=operation)
    obj["header"] = {"frame_id": link}
    return {"link_name": link, "object": obj, "touch_links": []}


def test_attached_objects_in_a_diff(app_client: TestClient, robot_id: str) -> None:
    _start(app_client, robot_id)
    url = f"/v1/robots/{robot_id}/scene"
    state = {"is_diff": True, "attached_collision_objects": [_held("cup")]}
    attached = app_client.put(url, json=_diff(robot_state=state))
    assert attached.status_code == 200, attached.text
    scene = app_client.get(url).json()
    assert [a["object"]["id"] for a in scene["attached_objects"]] == ["cup"]
    assert _ids(app_client, robot_id) == ["a", "b", "b#1", "c"]

    # A detach must say where the object is now: MoveIt leaves it in the world.
    detach = {"is_diff": True, "attached_collision_objects": [_held("cup", "REMOVE")]}
    unsaid = app_client.put(url, json=_diff(robot_state=detach))
    assert_detail(unsaid, 422, "'cup'", "world")
    assert app_client.get(url).json()["attached_objects"]
    placed = app_client.put(url, json=_diff(_box("cup", 1.2), robot_state=detach))
    assert placed.status_code == 200, placed.text
    scene = app_client.get(url).json()
    assert scene["attached_objects"] == []
    assert _ids(app_client, robot_id) == ["a", "b", "b#1", "c", "cup"]


def test_a_diff_whose_robot_state_is_not_a_diff_replaces_the_attached_objects(
    app_client: TestClient, robot_id: str
) -> None:
    url = f"/v1/robots/{robot_id}/scene"
    state = {"is_diff": True, "attached_collision_objects": [_held("cup")]}
    assert app_client.put(url, json=_diff(robot_state=state)).status_code == 200
    whole_state = {"attached_collision_objects": [_held("pen")]}
    put = app_client.put(url, json=_diff(robot_state=whole_state))
    assert put.status_code == 200, put.text
    held = app_client.get(url).json()["attached_objects"]
    assert [a["object"]["id"] for a in held] == ["pen"]
    assert any("cup" in w and "no longer attached" in w for w in put.json()["warnings"])


def test_a_diff_where_no_scene_is_there_to_change_is_refused() -> None:
    """Seed jobs and stored trajectories take whole scenes: a diff there has nothing to change."""
    with pytest.raises(SceneError, match="is_diff"):
        parse_scene(_diff(_box("d", 2.5)))
    assert parse_scene({**_diff(_box("d", 2.5)), "is_diff": False}).objects[0].id == "d"
