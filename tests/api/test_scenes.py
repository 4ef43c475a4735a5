"""PUT/PATCH/GET /v1/robots/{robot_id}/scene: versions, formats, errors, caching, concurrency."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
import sqlalchemy as sa
import yaml
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, ctx_of, register
from trajcache.geometry.scene.scene import make_scene
from trajcache.services.catalog.robots import current_scene
from trajcache.services.catalog.scene_writes import patch_scene

TABLE = {
    "id": "table",
    "type": "box",
    "size": [1.0, 0.5, 0.7],
    "pose": {"position": [1.0, 0.0, 0.35], "orientation": [0.0, 0.0, 0.0, 1.0]},
}
MOVEIT_TABLE = {
    "world": {
        "collision_objects": [
            {
                "id": "table",
                "header": {"frame_id": "world"},
                "primitives": [{"type": 1, "dimensions": [1.0, 0.5, 0.7]}],
                "primitive_poses": [
                    {
                        "position": {"x": 1.0, "y": 0.0, "z": 0.35},
                        "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                    }
                ],
                "operation": 0,
            }
        ]
    }
}


@contextmanager
def count_statements(engine: sa.Engine) -> Iterator[list[str]]:
    statements: list[str] = []

    def record(_conn: Any, _cursor: Any, statement: str, *_args: Any) -> None:
        statements.append(statement)

    sa.event.listen(engine, "before_cursor_execute", record)
    try:
        yield statements
    finally:
        sa.event.remove(engine, "before_cursor_execute", record)


def test_new_robot_has_the_empty_scene(app_client: TestClient, robot_id: str) -> None:
    body = app_client.get(f"/v1/robots/{robot_id}/scene").json()
    assert body == {"version": 0, "hash": make_scene([], {}).hash, "objects": [], "env": {},
                    "allowed_collisions": [], "attached_objects": []}  # fmt: skip


def test_put_and_get_scene(app_client: TestClient, robot_id: str) -> None:
    url = f"/v1/robots/{robot_id}/scene"
    put = app_client.put(url, json={"objects": [TABLE], "env": {"door": 0.5}})
    assert put.status_code == 200, put.text
    assert put.json()["version"] == 1
    got = app_client.get(url).json()
    assert got["version"] == 1
    assert got["hash"] == put.json()["hash"]
    assert got["env"] == {"door": 0.5}
    assert [o["id"] for o in got["objects"]] == ["table"]
    assert got["objects"][0]["size"] == pytest.approx(TABLE["size"])

    same = app_client.put(url, json={"objects": [TABLE], "env": {"door": 0.5}}).json()
    assert same == put.json()  # unchanged content: no new version
    changed = app_client.put(url, json={"objects": [TABLE], "env": {"door": 0.6}}).json()
    assert changed["version"] == 2
    assert changed["hash"] != put.json()["hash"]
    assert app_client.get(f"/v1/robots/{robot_id}").json()["scene_version"] == 2


def test_moveit_and_yaml_bodies_give_the_native_hash(app_client: TestClient, robot_id: str) -> None:
    url = f"/v1/robots/{robot_id}/scene"
    native = app_client.put(url, json={"objects": [TABLE]}).json()
    cleared = app_client.put(url, json={"objects": []}).json()
    assert cleared["version"] == 2
    moveit = app_client.put(url, json=MOVEIT_TABLE).json()
    assert moveit["hash"] == native["hash"]
    assert moveit["version"] == 3

    app_client.put(url, json={"objects": []})
    text = yaml.safe_dump({"objects": [TABLE]})
    as_yaml = app_client.put(url, content=text, headers={"content-type": "application/yaml"})
    assert as_yaml.status_code == 200, as_yaml.text
    assert as_yaml.json() == {"version": 5, "hash": native["hash"], "warnings": []}


def test_patch_scene(app_client: TestClient, robot_id: str) -> None:
    url = f"/v1/robots/{robot_id}/scene"
    app_client.put(url, json={"objects": [TABLE], "env": {"door": 0.0}})
    door = {"id": "door", "type": "box", "size": [0.05, 0.9, 2.0]}
    patched = app_client.patch(url, json={"upsert": [door], "env": {"door": 1.2}})
    assert patched.status_code == 200, patched.text
    assert patched.json()["version"] == 2
    got = app_client.get(url).json()
    assert sorted(o["id"] for o in got["objects"]) == ["door", "table"]
    assert got["env"] == {"door": 1.2}
    assert got["hash"] == patched.json()["hash"]

    removed = app_client.patch(url, json={"remove": ["table"], "env": {"door": None}}).json()
    assert removed["version"] == 3
    got = app_client.get(url).json()
    assert [o["id"] for o in got["objects"]] == ["door"]
    assert got["env"] == {}


def test_bad_scenes_are_422_naming_the_problem(app_client: TestClient, robot_id: str) -> None:
    url = f"/v1/robots/{robot_id}/scene"
    bad_box = {**TABLE, "id": "crate", "size": [1.0, -0.5, 0.7]}
    assert_detail(app_client.put(url, json={"objects": [bad_box]}), 422, "crate", "size[1]")
    no_size = {"id": "ball", "type": "sphere"}
    assert_detail(app_client.put(url, json={"objects": [no_size]}), 422, "ball")
    assert_detail(app_client.put(url, json={"objects": [TABLE, TABLE]}), 422, "duplicate")
    nan = '{"objects": [{"id": "ball", "type": "sphere", "size": [NaN]}]}'
    response = app_client.put(url, content=nan, headers={"content-type": "application/json"})
    assert_detail(response, 422, "NaN")
    assert_detail(
        app_client.put(url, content="{", headers={"content-type": "application/json"}),
        422,
        "not valid JSON",
    )
    assert_detail(
        app_client.put(url, content="[1, 2]", headers={"content-type": "application/json"}),
        422,
        "object",
    )
    assert_detail(
        app_client.put(url, content="a: &x 1\nb: *x\n", headers={"content-type": "text/yaml"}),
        422,
        "alias",
    )
    assert_detail(
        app_client.put(url, content=b"x", headers={"content-type": "image/png"}), 415, "png"
    )
    assert_detail(app_client.patch(url, json={"remove": ["nothing"]}), 422, "nothing")
    assert_detail(app_client.patch(url, json={"move": []}), 422, "body.move")
    assert_detail(app_client.patch(url, json={"upsert": [bad_box]}), 422, "crate")
    assert app_client.get(url).json()["version"] == 0  # nothing was stored


def test_unknown_robot_scene_is_404(app_client: TestClient) -> None:
    url = "/v1/robots/ghost/scene"
    assert_detail(app_client.get(url), 404, "ghost")
    assert_detail(app_client.put(url, json={"objects": [TABLE]}), 404, "ghost")
    assert_detail(app_client.patch(url, json={"upsert": [TABLE]}), 404, "ghost")


def test_scene_object_limit_is_413(client_factory: ClientFactory) -> None:
    client = client_factory(max_scene_objects=2)
    model_id = register(client)["model_id"]
    client.put("/v1/robots/r", json={"model_id": model_id})
    objects = [{**TABLE, "id": f"t{i}"} for i in range(3)]
    assert_detail(
        client.put("/v1/robots/r/scene", json={"objects": objects}), 413, "max_scene_objects=2"
    )
    client.put("/v1/robots/r/scene", json={"objects": objects[:2]})
    assert_detail(
        client.patch("/v1/robots/r/scene", json={"upsert": [objects[2]]}),
        413,
        "max_scene_objects",
    )


def test_objects_reaching_beyond_the_scene_extent_are_422(client_factory: ClientFactory) -> None:
    client = client_factory(max_scene_extent_m=50.0)
    model_id = register(client)["model_id"]
    client.put("/v1/robots/r", json={"model_id": model_id})
    url = "/v1/robots/r/scene"
    huge = {**TABLE, "id": "wall", "size": [1e300, 0.1, 0.1]}
    assert_detail(client.put(url, json={"objects": [huge]}), 422, "'wall'", "max_scene_extent_m")
    far = {**TABLE, "id": "crate", "pose": {"position": [60.0, 0.0, 0.0]}}
    assert_detail(client.put(url, json={"objects": [far]}), 422, "'crate'", "6")
    held = {"link": "tip", "object": {**huge, "id": "rod"}}
    assert_detail(client.put(url, json={"objects": [], "attached_objects": [held]}), 422, "'rod'")
    assert_detail(client.patch(url, json={"upsert": [far]}), 422, "max_scene_extent_m=50")
    assert client.get(url).json()["version"] == 0  # nothing was stored
    near = {**TABLE, "id": "crate", "pose": {"position": [40.0, 0.0, 0.0]}}
    assert client.put(url, json={"objects": [near]}).json()["version"] == 1


def test_identical_concurrent_first_puts_make_one_version(
    app_client: TestClient, robot_id: str
) -> None:
    url = f"/v1/robots/{robot_id}/scene"
    writers = 8
    lined_up = threading.Barrier(writers)
    answers: list[Any] = []

    def put() -> None:
        lined_up.wait()
        answers.append(app_client.put(url, json={"objects": [TABLE], "env": {"e": 1.0}}))

    threads = [threading.Thread(target=put) for _ in range(writers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert [a.status_code for a in answers] == [200] * writers, [a.text for a in answers]
    assert {(a.json()["version"], a.json()["hash"]) for a in answers} == {
        (1, answers[0].json()["hash"])
    }
    assert app_client.get(url).json()["version"] == 1


def test_current_scene_is_one_query_when_cached(app_client: TestClient, robot_id: str) -> None:
    put = app_client.put(f"/v1/robots/{robot_id}/scene", json={"objects": [TABLE]}).json()
    ctx = ctx_of(app_client)
    with ctx.sessions() as session, count_statements(ctx.engine) as statements:
        robot, scene, version = current_scene(session=session, scenes=ctx.scenes, robot_id=robot_id)
    assert (robot.id, scene.hash, version) == (robot_id, put["hash"], 1)
    assert len(statements) == 1, statements
    with ctx.sessions() as session:
        again = current_scene(session=session, scenes=ctx.scenes, robot_id=robot_id)[1]
    assert again is scene  # parsed once, then served from the SceneCache


def test_scene_is_parsed_from_the_database_on_a_cold_cache(
    client_factory: ClientFactory,
) -> None:
    first = client_factory()
    model_id = register(first)["model_id"]
    first.put("/v1/robots/r", json={"model_id": model_id})
    put = first.put("/v1/robots/r/scene", json={"objects": [TABLE], "env": {"e": 1.0}}).json()

    second = client_factory()
    ctx = ctx_of(second)
    assert len(ctx.scenes) == 0
    with ctx.sessions() as session:
        _, scene, version = current_scene(session=session, scenes=ctx.scenes, robot_id="r")
    assert (scene.hash, version) == (put["hash"], 1)
    assert [o.id for o in scene.objects] == ["table"]
    assert scene.env == {"e": 1.0}
    assert len(ctx.scenes) == 1


def test_concurrent_patches_all_apply(app_client: TestClient, robot_id: str) -> None:
    ctx = ctx_of(app_client)
    errors: list[BaseException] = []
    results: list[tuple[int, str]] = []

    def add(i: int) -> None:
        try:
            with ctx.sessions() as session:
                obj = {"id": f"o{i}", "type": "sphere", "size": [0.1]}
                results.append(
                    patch_scene(
                        session=session,
                        scenes=ctx.scenes,
                        robot_id=robot_id,
                        patch={"upsert": [obj]},
                    )
                )
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=add, args=(i,)) for i in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    assert sorted(v for v, _ in results) == [1, 2, 3, 4, 5, 6]
    got = app_client.get(f"/v1/robots/{robot_id}/scene").json()
    assert got["version"] == 6
    assert sorted(o["id"] for o in got["objects"]) == [f"o{i}" for i in range(6)]


def test_scene_versions_are_stored(app_client: TestClient, robot_id: str) -> None:
    url = f"/v1/robots/{robot_id}/scene"
    hashes = [app_client.put(url, json={"objects": [], "env": {"k": float(i)}}).json()["hash"]
              for i in range(3)]  # fmt: skip
    from trajcache.db.models import SceneVersion

    with ctx_of(app_client).sessions() as session:
        rows = session.execute(
            sa.select(SceneVersion.version, SceneVersion.hash, SceneVersion.payload)
            .where(SceneVersion.robot_id == robot_id)
            .order_by(SceneVersion.version)
        ).all()
    assert [(r.version, r.hash) for r in rows] == list(zip([1, 2, 3], hashes, strict=True))
    assert json.loads(json.dumps(rows[-1].payload))["env"] == {"k": 2.0}
