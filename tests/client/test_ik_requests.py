"""The client's IK methods: the native form as JSON read into IkResult, and MoveIt's
GetPositionIK as JSON or YAML, answered as sent (no transport, a scripted server)."""

from __future__ import annotations

import json
from typing import Any

import httpx
import pytest

import trajcache_client as tc
from tests.client.test_retries import Script
from trajcache_client import NO_RETRY, Client

IK_ANSWER: dict[str, Any] = {
    "status": "success",
    "state": [0.1, 0.2],
    "state_names": ["shoulder", "elbow"],
    "link": "fore",
    "position_error": 0.0001,
    "orientation_error": 0.001,
    "solutions": 3,
    "rejected": 0,
    "attempts": 3,
    "message": "",
    "timings_ms": {"db": 0.4, "solve": 1.0, "total": 1.5},
}
MOVEIT_ANSWER = {"solution": {}, "error_code": {"val": -31, "message": "", "source": "trajcache"}}


def _client(script: Script) -> Client:
    return Client("http://svc/", retry=NO_RETRY, transport=httpx.MockTransport(script))


def test_ik_sends_the_native_form_and_reads_its_answer() -> None:
    script = Script(ok=IK_ANSWER)
    request = {"link": "fore", "position": [0.3, 0.1, 0.5], "seed": [0.0, 0.0]}
    with _client(script) as client:
        answer = client.ik("r/1", request)
    assert isinstance(answer, tc.IkResult) and answer.ok and answer.state == [0.1, 0.2]
    sent = script.requests[0]
    assert (sent.method, sent.url.raw_path) == ("POST", b"/v1/robots/r%2F1/ik")
    assert json.loads(sent.content) == request


def test_get_position_ik_sends_mappings_as_json_and_text_as_yaml() -> None:
    script = Script(ok=MOVEIT_ANSWER)
    text = "ik_request:\n  ik_link_name: fore\n"
    with _client(script) as client:
        answer = client.get_position_ik("r1", {"ik_request": {"ik_link_name": "fore"}})
        client.get_position_ik("r1", text)
    assert answer["error_code"]["val"] == -31
    kinds = [r.headers["content-type"] for r in script.requests]
    assert kinds == ["application/json", "application/yaml"]
    assert script.requests[1].content == text.encode()


def test_an_ik_answer_of_another_shape_is_unexpected() -> None:
    script = Script(ok={"status": "success"})
    with _client(script) as client, pytest.raises(tc.UnexpectedResponseError, match="IkResult"):
        client.ik("r1", {"position": [0.0, 0.0, 0.0]})
