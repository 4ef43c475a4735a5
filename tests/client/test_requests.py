"""What the client sends: paths, bodies, headers and timeouts (httpx.MockTransport)."""

from __future__ import annotations

import importlib.metadata
import io
import json
import zipfile
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

import trajcache_client as tc
from tests.client.test_retries import PLAN, ROBOT, Script
from trajcache_client import NO_RETRY, Client, PlanOptions

MODEL = {
    "model_id": "m1",
    "name": "arm",
    "joint_names": ["a", "b"],
    "base": "fixed",
    "state_names": ["a", "b"],
    "created": True,
}


def _client(script: Script, **kwargs: Any) -> Client:
    return Client("http://svc/", retry=NO_RETRY, transport=httpx.MockTransport(script), **kwargs)


def _timeout(request: httpx.Request) -> dict[str, float | None]:
    timeout: dict[str, float | None] = request.extensions["timeout"]
    return timeout


def test_headers_carry_the_api_key_user_agent_and_extras() -> None:
    script = Script(ok=ROBOT)
    with _client(script, api_key="k-123", headers={"x-fleet": "north"}) as client:
        client.get_robot("r1")
    headers = script.requests[0].headers
    assert headers["authorization"] == "Bearer k-123"
    assert headers["user-agent"] == f"trajcache-client/{tc.__version__}"
    assert headers["x-fleet"] == "north" and headers["accept"] == "application/json"


def test_path_segments_are_escaped() -> None:
    script = Script(ok=ROBOT)
    with _client(script) as client:
        client.get_robot("a/b c")
    assert script.requests[0].url.raw_path == b"/v1/robots/a%2Fb%20c"


def test_plan_sends_numbers_and_only_the_options_given() -> None:
    script = Script(ok=PLAN)
    with _client(script) as client:
        client.plan("r1", np.array([0.0, 0.5]), (1, 2), PlanOptions(threshold=0.1, match="arm"))
        client.plan("r1", [0, 0], [1, 1], {"fallback": False, "timing": {"max_velocity": 1.0}})
        client.plan("r1", [0, 0], [1, 1])
    bodies = [json.loads(r.content) for r in script.requests]
    assert bodies[0] == {
        "start": [0.0, 0.5],
        "goal": [1.0, 2.0],
        "options": {"threshold": 0.1, "match": "arm"},
    }
    assert bodies[1]["options"] == {"fallback": False, "timing": {"max_velocity": 1.0}}
    assert bodies[2]["options"] == {}


def test_invalid_plan_options_are_refused_before_sending() -> None:
    script = Script(ok=PLAN)
    with _client(script) as client, pytest.raises(ValueError, match="threshold"):
        client.plan("r1", [0, 0], [1, 1], {"threshold": -1})
    assert script.requests == []


def test_plan_waits_for_the_planning_budget_it_asks_for() -> None:
    script = Script(ok=PLAN)
    with _client(script, timeout=5.0) as client:
        client.plan("r1", [0, 0], [1, 1], {"budget_s": 20})
        client.plan("r1", [0, 0], [1, 1], {"budget_s": 0.5})
        client.plan("r1", [0, 0], [1, 1])
    budgeted, short, default = (_timeout(r) for r in script.requests)
    assert budgeted == {"connect": 5.0, "read": 30.0, "write": 5.0, "pool": 5.0}
    assert short["read"] == 10.5 and default["read"] == 5.0


def test_default_timeouts_are_set() -> None:
    script = Script(ok=ROBOT)
    with _client(script) as client:
        client.get_robot("r1")
    assert _timeout(script.requests[0]) == {
        "connect": 5.0,
        "read": 30.0,
        "write": 30.0,
        "pool": 30.0,
    }


def test_register_model_sends_json_without_an_archive() -> None:
    script = Script(ok=MODEL)
    with _client(script) as client:
        model = client.register_model("<robot/>", base="planar", joint_names=("a", "b"))
    request = script.requests[0]
    assert request.headers["content-type"] == "application/json"
    assert json.loads(request.content) == {
        "urdf": "<robot/>",
        "base": "planar",
        "joint_names": ["a", "b"],
    }
    assert model == tc.RobotModel.model_validate(MODEL)


def test_register_model_uploads_an_archive_as_multipart(tmp_path: Path) -> None:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("meshes/link.stl", b"solid x\nendsolid x\n")
    path = tmp_path / "arm_meshes.zip"
    path.write_bytes(buffer.getvalue())
    script = Script(ok=MODEL)
    with _client(script) as client:
        client.register_model("<robot/>", joint_names=["a", "b"], name="arm", archive=path)
    request = script.requests[0]
    media, boundary = request.headers["content-type"].split("; boundary=")
    assert media == "multipart/form-data"
    parts = request.content.split(b"--" + boundary.encode())
    named = {p.split(b'name="')[1].split(b'"')[0]: p for p in parts if b'name="' in p}
    assert set(named) == {b"urdf", b"base", b"joint_names", b"name", b"archive"}
    assert b"\r\n\r\na,b\r\n" in named[b"joint_names"]
    assert b'filename="arm_meshes.zip"' in named[b"archive"]
    assert buffer.getvalue() in named[b"archive"]


def test_put_scene_sends_mappings_as_json_and_text_as_yaml() -> None:
    script = Script(ok={"version": 1, "hash": "h"})
    with _client(script) as client:
        client.put_scene("r1", {"objects": [], "env": {"door": 0.5}})
        client.put_scene("r1", "objects: []\n")
        client.put_scene("r1", b'{"objects": []}', media_type="application/json")
    kinds = [(r.method, r.headers["content-type"], r.content) for r in script.requests]
    assert kinds == [
        ("PUT", "application/json", b'{"objects": [], "env": {"door": 0.5}}'),
        ("PUT", "application/yaml", b"objects: []\n"),
        ("PUT", "application/json", b'{"objects": []}'),
    ]


def test_patch_scene_and_list_filters() -> None:
    page = {"items": [], "total": 0, "limit": 10, "offset": 20}
    script = Script(
        httpx.Response(200, json={"version": 2, "hash": "h"}), httpx.Response(200, json=page)
    )
    with _client(script) as client:
        client.patch_scene("r1", upsert=[{"id": "door"}], env={"door": None})
        listed = client.list_trajectories(source="sim", robot_id="r1", limit=10, offset=20)
    patch, listing = script.requests
    assert json.loads(patch.content) == {
        "upsert": [{"id": "door"}],
        "remove": [],
        "env": {"door": None},
    }
    assert dict(listing.url.params) == {
        "source": "sim",
        "robot_id": "r1",
        "limit": "10",
        "offset": "20",
    }
    assert listed.total == 0 and listed.offset == 20


def test_answers_keep_fields_a_newer_service_adds() -> None:
    script = Script(ok={**PLAN, "trajectory": {"joint_names": ["a", "b"], "points": []}})
    with _client(script) as client:
        answer = client.plan("r1", [0, 0], [1, 1])
    assert answer.model_extra == {"trajectory": {"joint_names": ["a", "b"], "points": []}}


def test_delete_answers_none() -> None:
    script = Script(httpx.Response(204))
    with _client(script) as client:
        assert client.delete_trajectory(5) is None
    assert script.requests[0].method == "DELETE"
    assert script.requests[0].url.path == "/v1/trajectories/5"


def test_the_public_surface_is_importable_and_typed() -> None:
    for name in tc.__all__:
        assert getattr(tc, name) is not None
    typed = Path(tc.__file__).with_name("py.typed")
    assert typed.is_file()


def test_every_client_method_has_an_async_twin() -> None:
    def public(cls: type) -> set[str]:
        return {n for n in vars(cls) if not n.startswith("_")}

    assert public(tc.Client) - {"close"} == public(tc.AsyncClient) - {"aclose"}


def test_the_client_version_is_the_distributions() -> None:
    assert tc.__version__ == importlib.metadata.version("trajcache")
