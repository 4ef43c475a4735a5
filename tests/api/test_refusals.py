"""Refused plan requests (a plan route's 4xx) are plan events of their own: status `refused`,
the reason kept (never the body), counted apart from failures; a caller refused by the key
check (401, 403) leaves none."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, ctx_of, register
from tests.waiting import wait_until
from trajcache.services.catalog.keys import create_key

BLOCKER = {"id": "blocker", "type": "box", "size": [0.1] * 3, "pose": {"position": [0, 0, 0.3]}}
START_BLOCKED = {"start": [0.0, 0.0], "goal": [1.0, 0.0], "options": {"fallback": False}}
MARKER = 0.123456  # a request value that must not reach the event


def _events(client: TestClient, headers: dict[str, str] | None = None, **query: Any) -> Any:
    ctx_of(client).records.flush(timeout=10)
    reply = client.get("/v1/plan-events", params=query, headers=headers)
    assert reply.status_code == 200, reply.text
    return reply.json()["items"]


def _stats(client: TestClient, headers: dict[str, str] | None = None) -> Any:
    reply = client.get("/v1/stats", params={"window": "1h"}, headers=headers)
    assert reply.status_code == 200, reply.text
    return reply.json()


def _robot(client: TestClient, headers: dict[str, str] | None = None) -> str:
    model_id = register(client, name="two-joint")["model_id"] if headers is None else None
    if model_id is None:
        reply = client.post("/v1/robot-models", json={"urdf": _urdf()}, headers=headers)
        model_id = reply.json()["model_id"]
    reply = client.put("/v1/robots/robot-1", json={"model_id": model_id}, headers=headers)
    assert reply.status_code == 201, reply.text
    reply = client.put("/v1/robots/robot-1/scene", json={"objects": [BLOCKER]}, headers=headers)
    assert reply.status_code == 200, reply.text
    return str(model_id)


def _urdf() -> str:
    from tests.robots import TWO_JOINT_URDF

    return TWO_JOINT_URDF


def test_refusals_are_recorded_with_their_reason_and_counted_apart(
    app_client: TestClient,
) -> None:
    model_id = _robot(app_client)
    plan = "/v1/robots/robot-1/plan"
    assert app_client.post(plan, json=START_BLOCKED).status_code == 422  # start in collision
    wrong = {"start": [MARKER, 0.0, 0.0], "goal": [1.0, 0.0]}
    assert app_client.post(plan, json=wrong).status_code == 422  # three values for two joints
    assert app_client.post(plan, json={"start": [0, 0], "goal": [1, 0], "x": 1}).status_code == 422
    ghost = app_client.post("/v1/robots/ghost/plan", json={"start": [0, 0], "goal": [1, 0]})
    assert ghost.status_code == 404
    clear = {"start": [1.0, 0.0], "goal": [1.2, 0.0], "options": {"fallback": False}}
    assert app_client.post(plan, json=clear).json()["status"] == "miss"  # answered

    refused = _events(app_client, status="refused")
    assert len(refused) == 4
    by_robot = {e["robot_id"]: e for e in refused}
    assert by_robot["ghost"]["model_id"] == "" and by_robot["ghost"]["error"].startswith("404: ")
    mine = [e for e in refused if e["robot_id"] == "robot-1"]
    assert {e["model_id"] for e in mine} == {model_id}
    reasons = [e["error"] for e in mine]
    collision = next(r for r in reasons if "collision" in r)
    assert collision.startswith("422: start state is in collision") and "blocker" in collision
    assert any("x" in r and r.startswith("422: ") for r in reasons if r != collision)
    assert all(str(MARKER) not in r for r in reasons)  # the reason, not the body
    for e in refused:
        assert e["source"] is None and e["trajectory_id"] is None and e["candidates_tried"] == 0

    totals = _stats(app_client)["totals"]
    assert totals["refusals"] == 4 and totals["failures"] == 0
    assert totals["requests"] == 1 and totals["misses"] == 1  # refusals are not requests
    assert totals["total_ms"]["sum_ms"] == _events(app_client, status="miss")[0]["total_ms"]
    groups = {g["key"]: g for g in _stats(app_client)["groups"]}
    assert groups["robot-1"]["refusals"] == 3 and groups["ghost"]["refusals"] == 1
    assert groups["ghost"]["requests"] == 0 and groups["ghost"]["hit_rate"] is None
    assert sum(b["refusals"] for b in _stats(app_client)["series"]) == 4


def test_a_robot_id_that_names_no_robot_leaves_no_event(
    client_factory: ClientFactory, caplog: pytest.LogCaptureFixture
) -> None:
    """A 129-character id is a 422 whose refusal leaves no event (PostgreSQL's robot id column
    would refuse the row, and the record would be lost with an error in the log)."""
    client = client_factory()
    body = {"start": [0, 0], "goal": [1, 0]}
    assert client.post(f"/v1/robots/{'0' * 129}/plan", json=body).status_code == 422
    assert client.post("/v1/robots/ghost/plan", json=body).status_code == 404
    assert [e["robot_id"] for e in _events(client, status="refused")] == ["ghost"]
    assert not [r for r in caplog.records if "rejected by the database" in r.getMessage()]


def test_the_moveit_route_records_its_in_band_refusals(app_client: TestClient) -> None:
    _robot(app_client)
    request = {
        "group_name": "arm",
        "start_state": {"joint_state": {"name": ["shoulder", "elbow"], "position": [0.0, 0.0]}},
        "goal_constraints": [
            {
                "joint_constraints": [
                    {"joint_name": "shoulder", "position": 1.0},
                    {"joint_name": "elbow", "position": 0.0},
                ]
            }
        ],
    }
    reply = app_client.post("/v1/robots/robot-1/motion-plan", json=request)
    assert reply.status_code == 200, reply.text
    assert reply.json()["error_code"]["val"] == -10  # START_STATE_IN_COLLISION
    [event] = _events(app_client, status="refused")
    assert event["error"].startswith("MoveIt START_STATE_IN_COLLISION (-10): start state")


def _key(client: TestClient, role: str, robots: list[str] | None = None) -> dict[str, str]:
    ctx = ctx_of(client)
    with ctx.sessions() as session:
        _, secret = create_key(session=session, name=role, role=role, robot_ids=robots)
    ctx.keys.clear()
    return {"Authorization": f"Bearer {secret}"}


@pytest.mark.parametrize("body", [START_BLOCKED, {"start": "nonsense"}], ids=["state", "body"])
def test_callers_the_key_check_refuses_leave_no_refusal(
    client_factory: ClientFactory, body: dict[str, Any]
) -> None:
    client = client_factory(auth_mode="on", auth_cache_ttl_s=0)
    admin = _key(client, "admin")
    _robot(client, admin)
    other = _key(client, "robot", ["robot-2"])
    plan = "/v1/robots/robot-1/plan"
    assert client.post(plan, json=body).status_code == 401  # no key
    assert client.post(plan, json=body, headers={"X-API-Key": "wrong"}).status_code == 401
    assert client.post(plan, json=body, headers=other).status_code == 403  # not its robot
    assert _events(client, admin, status="refused") == []
    assert client.post(plan, json=body, headers=admin).status_code == 422
    assert wait_until(lambda: len(_events(client, admin, status="refused")) == 1)
    assert _stats(client, admin)["totals"]["refusals"] == 1
