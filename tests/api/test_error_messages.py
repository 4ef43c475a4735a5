"""Errors that name the mistake: unknown names with the closest valid one, the valid values of a
fixed set, the form a union input was closest to, and paths the service does not take."""

from __future__ import annotations

from typing import Any

import pydantic
import pytest
import yaml
from fastapi.testclient import TestClient

import trajcache.main  # noqa: F401  (every request schema loaded)
from tests.api.conftest import register
from tests.robots import TWO_JOINT_URDF
from trajcache.core.request_model import UNKNOWN_FIELD, RequestModel

PANDA_LIKE = TWO_JOINT_URDF.replace('"shoulder"', '"panda_joint1"').replace(
    '"elbow"', '"panda_joint2"'
)
NO_FALLBACK = {"fallback": False}


def _object(**fields: Any) -> dict[str, Any]:
    return {"id": "crate", "type": "box", "size": [0.1, 0.1, 0.1], **fields}


# (name, method, path, request keywords, status, needles, words that must not appear)
CASES: list[tuple[str, str, str, dict[str, Any], int, list[str], list[str]]] = [
    (
        "misspelt joint in a map",
        "POST",
        "/v1/robots/r/plan",
        {"json": {"start": {"panda_joint1": 0, "panda_joint_2": 0}, "goal": [0, 0],
                  "options": NO_FALLBACK}},
        422,
        ["start: unknown joint 'panda_joint_2' (did you mean 'panda_joint2'?)"],
        ["lacks"],
    ),
    (
        "NaN in a state",
        "POST",
        "/v1/robots/r/plan",
        {"content": '{"start": [0, NaN], "goal": [0, 0]}',
         "headers": {"content-type": "application/json"}},
        422,
        ["body.start[1]: nan is not a finite number"],
        ["dictionary", "valid string", "list[float]"],
    ),
    (
        "a state of no form",
        "POST",
        "/v1/robots/r/plan",
        {"json": {"start": True, "goal": [0, 0]}},
        422,
        ["body.start: Input should be one of: a valid list; a valid dictionary; a valid string"],
        ["list[float]"],
    ),
    (
        "unknown shape type",
        "PUT",
        "/v1/robots/r/scene",
        {"json": {"objects": [_object(type="cube")]}},
        422,
        ["unknown type 'cube' (did you mean 'box'?)", "box, sphere, cylinder, capsule, mesh"],
        [],
    ),
    (
        "misplaced position",
        "PUT",
        "/v1/robots/r/scene",
        {"json": {"objects": [_object(position=[1.0, 0.0, 0.0])]}},
        422,
        ["unknown field 'position' (did you mean 'pose'?)"],
        [],
    ),
    (
        "misspelt option",
        "POST",
        "/v1/robots/r/plan",
        {"json": {"start": [0, 0], "goal": [0, 0], "options": {"treshold": 0.1}}},
        422,
        ["body.options.treshold: unknown field 'treshold' (did you mean 'threshold'?)"],
        ["Extra inputs"],
    ),
    (
        "value outside a fixed set",
        "POST",
        "/v1/robots/r/plan",
        {"json": {"start": [0, 0], "goal": [0, 0], "options": {"match": "arms"}}},
        422,
        ["body.options.match: unknown value 'arms' (did you mean 'arm'?); valid: full, arm"],
        [],
    ),
    (
        "misspelt MoveIt field",
        "POST",
        "/v1/robots/r/motion-plan",
        {"content": yaml.safe_dump({"group_name": "arm", "goal_constraint": []}),
         "headers": {"content-type": "application/yaml"}},
        422,
        ["unknown field 'goal_constraint' (did you mean 'goal_constraints'?)"],
        [],
    ),
    (
        "a file under a wrong form field",
        "POST",
        "/v1/robot-models",
        {"files": {"file": ("panda.urdf", TWO_JOINT_URDF.encode())}},
        422,
        ["unknown form field 'file'", "urdf, srdf,", "archive", "files: urdf, srdf, archive"],
        ["must not be a file"],
    ),
    (
        "an unknown path",
        "GET",
        "/v1/robot",
        {},
        404,
        ["no such path: /v1/robot", "/docs"],
        [],
    ),
]  # fmt: skip


@pytest.fixture
def panda_like(app_client: TestClient) -> TestClient:
    model_id = register(app_client, PANDA_LIKE)["model_id"]
    assert app_client.put("/v1/robots/r", json={"model_id": model_id}).status_code == 201
    return app_client


@pytest.mark.parametrize(
    ("method", "path", "request_kw", "status", "needles", "absent"),
    [pytest.param(*case[1:], id=case[0]) for case in CASES],
)
def test_the_message_names_the_mistake(
    panda_like: TestClient,
    method: str,
    path: str,
    request_kw: dict[str, Any],
    status: int,
    needles: list[str],
    absent: list[str],
) -> None:
    reply = panda_like.request(method, path, **request_kw)
    assert reply.status_code == status, reply.text
    detail = reply.json()["detail"]
    for needle in needles:
        assert needle in detail, f"{needle!r} not in {detail!r}"
    for word in absent:
        assert word not in detail, f"{word!r} in {detail!r}"


def test_a_trailing_slash_is_answered_with_the_path_to_use(panda_like: TestClient) -> None:
    body = {"start": [0, 0], "goal": [0, 0], "options": NO_FALLBACK}
    reply = panda_like.post("/v1/robots/r/plan/?x=1", json=body, follow_redirects=False)
    assert reply.status_code == 307 and reply.headers["location"] == "/v1/robots/r/plan?x=1"
    assert "/v1/robots/r/plan/ is served at /v1/robots/r/plan" in reply.json()["detail"]
    followed = panda_like.post("/v1/robots/r/plan/", json=body)
    assert followed.status_code == 200 and followed.json()["status"] in ("success", "miss")
    dashboard = panda_like.get("/dashboard", follow_redirects=False)
    assert dashboard.status_code == 307 and dashboard.headers["location"] == "/dashboard/"


def _request_models() -> list[type[RequestModel]]:
    out: list[type[RequestModel]] = []
    todo: list[type[RequestModel]] = [RequestModel]
    while todo:
        for sub in todo.pop().__subclasses__():
            todo.append(sub)
            if sub.model_fields:
                out.append(sub)
    return out


def test_every_forbidding_schema_names_unknown_fields() -> None:
    """One mechanism for every request schema: a model that forbids unknown fields is a
    RequestModel, whose error names a misspelt field and the one it was meant to be."""
    forbidding = set()
    todo: list[type[pydantic.BaseModel]] = [pydantic.BaseModel]
    while todo:
        for sub in todo.pop().__subclasses__():
            todo.append(sub)
            if sub.__module__.startswith("trajcache") and sub.model_config.get("extra") == "forbid":
                forbidding.add(sub)
    models = _request_models()
    assert len(models) >= 20
    assert [m for m in forbidding if not issubclass(m, RequestModel)] == []
    for model in models:
        name, field = next(iter(model.model_fields.items()))
        key = field.alias or name
        with pytest.raises(pydantic.ValidationError) as caught:
            model.model_validate({f"{key}x": 1})
        error = caught.value.errors()[0]
        assert error["type"] == UNKNOWN_FIELD, (model, error)
        assert f"unknown field '{key}x' (did you mean '{key}'?)" in error["msg"], error["msg"]
