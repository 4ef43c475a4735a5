"""What the client sends: paths, bodies, headers and timeouts (httpx.MockTransport)."""

from __future__ import annotations

import importlib.metadata
import io
import json
import ssl
import zipfile
from email import policy
from email.message import EmailMessage
from email.parser import BytesParser
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

import trajcache_client as tc
from tests.client.conftest import FAST_RETRY
from tests.client.test_retries import PLAN, ROBOT, Script
from tests.robots import OPAQUE_URDF
from trajcache_client import NO_RETRY, Client, PlanOptions

MODEL = {
    "model_id": "m1",
    "name": "arm",
    "joint_names": ["a", "b"],
    "base": "fixed",
    "state_names": ["a", "b"],
    "created": True,
}


def _client(script: Script, retry: tc.Retry = NO_RETRY, **kwargs: Any) -> Client:
    return Client("http://svc/", retry=retry, transport=httpx.MockTransport(script), **kwargs)


def _form(request: httpx.Request) -> dict[str, tuple[str | None, bytes]]:
    """The parts of a multipart/form-data request: name -> (file name or None, content)."""
    head = f"content-type: {request.headers['content-type']}\r\n\r\n".encode()
    message = BytesParser(policy=policy.HTTP).parsebytes(head + request.content)
    assert isinstance(message, EmailMessage) and message.get_content_type() == "multipart/form-data"
    parts: dict[str, tuple[str | None, bytes]] = {}
    for part in message.iter_parts():
        name = str(part.get_param("name", header="content-disposition"))
        parts[name] = (part.get_filename(), part.get_payload(decode=True))
    return parts


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


def test_plan_sends_states_as_maps_by_joint_name_or_as_named_states() -> None:
    script = Script(ok=PLAN)
    with _client(script) as client:
        client.plan("r1", {"a": 0, "b": np.float64(0.5)}, "ready")
        client.plan("r1", "ready", np.array([1, 2]))
    bodies = [json.loads(r.content) for r in script.requests]
    assert bodies[0] == {"start": {"a": 0.0, "b": 0.5}, "goal": "ready", "options": {}}
    assert bodies[1] == {"start": "ready", "goal": [1.0, 2.0], "options": {}}


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
        model = client.register_model(OPAQUE_URDF, base="planar", joint_names=("a", "b"))
    request = script.requests[0]
    assert request.headers["content-type"] == "application/json"
    assert json.loads(request.content) == {
        "urdf": OPAQUE_URDF,
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
        client.register_model(OPAQUE_URDF, joint_names=["a", "b"], name="arm", archive=path)
    request = script.requests[0]
    media, boundary = request.headers["content-type"].split("; boundary=")
    assert media == "multipart/form-data"
    parts = request.content.split(b"--" + boundary.encode())
    named = {p.split(b'name="')[1].split(b'"')[0]: p for p in parts if b'name="' in p}
    assert set(named) == {b"urdf", b"base", b"joint_names", b"name", b"archive"}
    assert b"\r\n\r\na,b\r\n" in named[b"joint_names"]
    assert b'filename="arm_meshes.zip"' in named[b"archive"]
    assert buffer.getvalue() in named[b"archive"]


SRDF = '<robot name="arm"><group name="arm"><joint name="a"/><joint name="b"/></group></robot>'


def test_register_model_sends_the_srdf_group_held_values_and_limits_as_json() -> None:
    script = Script(ok=MODEL)
    with _client(script) as client:
        client.register_model(
            OPAQUE_URDF,
            srdf=SRDF,
            group="arm",
            joint_values={"finger": 1},
            acceleration_limits=2,
            jerk_limits={"a": 50, "b": 60.5},
            end_effector_link="tool",
        )
        client.register_model(OPAQUE_URDF, srdf=SRDF, joint_values="open")
    first, second = (json.loads(r.content) for r in script.requests)
    assert first == {
        "urdf": OPAQUE_URDF,
        "srdf": SRDF,
        "base": "fixed",
        "group": "arm",
        "joint_values": {"finger": 1.0},
        "acceleration_limits": 2.0,
        "jerk_limits": {"a": 50.0, "b": 60.5},
        "end_effector_link": "tool",
    }
    assert second == {"urdf": OPAQUE_URDF, "srdf": SRDF, "base": "fixed", "joint_values": "open"}


def test_multipart_registration_sends_the_srdf_as_a_file_and_values_as_json_text() -> None:
    script = Script(ok=MODEL)
    with _client(script) as client:
        client.register_model(
            OPAQUE_URDF,
            srdf=SRDF,
            group="arm",
            joint_values={"finger": 0.02},
            joint_names=["a", "b"],
            archive=b"PK",
            acceleration_limits={"a": 3},
            jerk_limits=40,
        )
        client.register_model(OPAQUE_URDF, joint_values="open", archive=b"PK")
    full, named = (_form(r) for r in script.requests)
    assert full == {
        "urdf": (None, OPAQUE_URDF.encode()),
        "base": (None, b"fixed"),
        "joint_names": (None, b"a,b"),
        "group": (None, b"arm"),
        "joint_values": (None, b'{"finger": 0.02}'),
        "acceleration_limits": (None, b'{"a": 3.0}'),
        "jerk_limits": (None, b"40.0"),
        "archive": ("meshes.zip", b"PK"),
        "srdf": ("robot.srdf", SRDF.encode()),
    }
    assert named["joint_values"] == (None, b"open") and "srdf" not in named


def test_put_robot_sends_its_kind_and_held_values_only_when_given() -> None:
    script = Script(ok={**ROBOT, "kind": "sim", "joint_values": {"finger": 0.02}})
    with _client(script) as client:
        robot = client.put_robot("r1", "m1", kind="sim", joint_values={"finger": 0.02})
        client.put_robot("r1", "m1")
        client.put_robot("r1", "m1", joint_values={})
    bodies = [json.loads(r.content) for r in script.requests]
    assert bodies == [
        {"model_id": "m1", "kind": "sim", "joint_values": {"finger": 0.02}},
        {"model_id": "m1"},
        {"model_id": "m1", "joint_values": {}},  # {} returns to the model's values
    ]
    assert robot.kind == "sim" and robot.joint_values == {"finger": 0.02}


@pytest.mark.anyio
async def test_the_async_client_sends_the_same_new_fields() -> None:
    answers = [MODEL, ROBOT, PLAN]
    sent: list[httpx.Request] = []

    def handler(request: httpx.Request) -> httpx.Response:
        sent.append(request)
        return httpx.Response(200, json=answers[len(sent) - 1])

    transport = httpx.MockTransport(handler)
    async with tc.AsyncClient("http://svc", retry=NO_RETRY, transport=transport) as client:
        await client.register_model(OPAQUE_URDF, srdf=SRDF, group="arm", joint_values="open")
        await client.put_robot("r1", "m1", kind="real", joint_values={"finger": 0})
        await client.plan("r1", {"a": 0, "b": 0}, "ready")
    registration, robot, plan = (json.loads(r.content) for r in sent)
    assert (registration["srdf"], registration["group"], registration["joint_values"]) == (
        SRDF,
        "arm",
        "open",
    )
    assert robot == {"model_id": "m1", "kind": "real", "joint_values": {"finger": 0.0}}
    assert plan["start"] == {"a": 0.0, "b": 0.0} and plan["goal"] == "ready"


MOTION_PLAN = {"error_code": {"val": 1, "message": "", "source": "trajcache"}, "trajectory": {}}
MOVEIT_YAML = "group_name: arm\nallowed_planning_time: 2.0\n"


def test_motion_plan_sends_mappings_as_json_and_text_as_yaml() -> None:
    script = Script(ok=MOTION_PLAN)
    request = {"group_name": "arm", "allowed_planning_time": 25}
    with _client(script, timeout=5.0) as client:
        answer = client.motion_plan("r/1", request)
        client.motion_plan("r/1", MOVEIT_YAML)
        client.motion_plan("r/1", {"motion_plan_request": request})
        client.motion_plan("r/1", {"request": {"allowed_planning_time": 0.0}})
    sent = [(r.method, r.url.raw_path, r.headers["content-type"]) for r in script.requests]
    assert sent[:2] == [
        ("POST", b"/v1/robots/r%2F1/motion-plan", "application/json"),
        ("POST", b"/v1/robots/r%2F1/motion-plan", "application/yaml"),
    ]
    assert json.loads(script.requests[0].content) == request
    assert script.requests[1].content == MOVEIT_YAML.encode()
    # It waits for the planning time it asks for, bare or wrapped; 0 is the service default.
    assert [_timeout(r)["read"] for r in script.requests] == [35.0, 5.0, 35.0, 5.0]
    assert answer == MOTION_PLAN


def test_motion_plan_is_retried_like_plan_only_on_503() -> None:
    bad_gateway, unavailable = Script(502, ok=MOTION_PLAN), Script(503, ok=MOTION_PLAN)
    with _client(bad_gateway, retry=FAST_RETRY) as client, pytest.raises(tc.ServerError):
        client.motion_plan("r1", {"group_name": "arm"})
    with _client(unavailable, retry=FAST_RETRY) as client:
        assert client.motion_plan("r1", {"group_name": "arm"}) == MOTION_PLAN
    assert (len(bad_gateway.requests), len(unavailable.requests)) == (1, 2)


def test_a_motion_plan_answer_that_is_not_an_object_is_unexpected() -> None:
    script = Script(ok=[1, 2])
    with _client(script) as client, pytest.raises(tc.UnexpectedResponseError, match="motion-plan"):
        client.motion_plan("r1", {"group_name": "arm"})


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


def test_clients_share_one_tls_context_unless_given_their_own() -> None:
    """httpx loads the CA bundle per client; ours load it once per process, and a context or
    `verify=False` given to a client is the one it uses."""
    shared = [
        Client("http://a")._http._transport._pool._ssl_context,  # type: ignore[attr-defined]
        tc.AsyncClient("https://b")._http._transport._pool._ssl_context,  # type: ignore[attr-defined]
    ]
    assert shared[0] is shared[1]
    assert shared[0].verify_mode is ssl.CERT_REQUIRED
    own = ssl.create_default_context()
    given = Client("http://a", verify=own)._http._transport._pool._ssl_context  # type: ignore[attr-defined]
    assert given is own
    unverified = Client("http://a", verify=False)._http._transport._pool._ssl_context  # type: ignore[attr-defined]
    assert unverified.verify_mode is ssl.CERT_NONE
