"""POST /v1/robots/{id}/plan through the real app: hits, reversal, misses, bad input, events."""

from __future__ import annotations

import math
import threading
from typing import Any

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

from tests.api.conftest import assert_detail, ctx_of, register
from trajcache.db.models import PlanEvent, Trajectory

PATH = [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]


def _box(oid: str, position: list[float], size: float) -> dict[str, Any]:
    return {"id": oid, "type": "box", "size": [size] * 3, "pose": {"position": position}}


def _store(client: TestClient, model_id: str, states: list[list[float]]) -> int:
    reply = client.post("/v1/trajectories", json={"model_id": model_id, "states": states})
    assert reply.status_code in (200, 201), reply.text
    return int(reply.json()["trajectory_id"])


def _plan(client: TestClient, start: list[float], goal: list[float], **options: Any) -> Any:
    body = {"start": start, "goal": goal, "options": {"fallback": False, **options}}
    return client.post("/v1/robots/robot-1/plan", json=body)


def test_near_request_is_served_from_cache_with_adapted_endpoints(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    stored = _store(app_client, model_id, PATH)
    reply = _plan(app_client, [0.05, 0.02], [0.98, -0.03])
    assert reply.status_code == 200, reply.text
    body = reply.json()
    assert body["status"] == "success" and body["source"] == "cache"
    assert body["trajectory_id"] == stored and body["candidates_tried"] == 1
    assert body["states"][0] == [0.05, 0.02] and body["states"][-1] == [0.98, -0.03]
    assert set(body["timings_ms"]) >= {"lookup", "validate", "plan", "total"}


def test_reversed_trajectory_serves_the_return_trip(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    stored = _store(app_client, model_id, PATH)
    body = _plan(app_client, [1.0, 0.0], [0.0, 0.0]).json()
    assert body["source"] == "cache" and body["trajectory_id"] == stored
    assert [round(s[0], 6) for s in body["states"]] == [1.0, 0.5, 0.0]


def test_far_request_misses_without_fallback(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    _store(app_client, model_id, PATH)
    body = _plan(app_client, [0.0, 0.5], [1.0, 0.0]).json()  # start 0.5 rad away on the elbow
    assert body["status"] == "miss" and body["source"] is None and body["states"] is None
    assert body["candidates_tried"] == 0


def test_blocked_candidate_is_rejected_and_its_failure_recorded(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    stored = _store(app_client, model_id, PATH)
    # A small box in the sweep of the upper arm at shoulder ≈ 0.5 rad, clear of both endpoints.
    blocker = _box("blocker", [0.25 * math.sin(0.5), 0.0, 0.1 + 0.25 * math.cos(0.5)], 0.04)
    assert (
        app_client.put("/v1/robots/robot-1/scene", json={"objects": [blocker]}).status_code == 200
    )
    body = _plan(app_client, [0.0, 0.0], [1.0, 0.0]).json()
    assert body["status"] == "miss" and body["candidates_tried"] == 1
    assert body["rejected"][0]["trajectory_id"] == stored
    assert "blocker" in body["rejected"][0]["reason"]
    with ctx_of(app_client).sessions() as session:
        row = session.get(Trajectory, stored)
        assert row is not None and row.failures == 1 and row.hits == 0


def test_start_in_collision_is_422_naming_link_and_object(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    _store(app_client, model_id, PATH)
    scene = {"objects": [_box("blocker", [0.0, 0.0, 0.3], 0.1)]}
    assert app_client.put("/v1/robots/robot-1/scene", json=scene).status_code == 200
    assert_detail(_plan(app_client, [0.0, 0.0], [1.0, 0.0]), 422, "start", "upper", "blocker")


def test_bad_states_are_422(app_client: TestClient, model_id: str, robot_id: str) -> None:
    assert_detail(_plan(app_client, [0.0], [1.0, 0.0]), 422, "start")
    assert_detail(_plan(app_client, [0.0, 0.0], [1.0, 1.7]), 422, "elbow")
    raw = '{"start": [NaN, 0.0], "goal": [1.0, 0.0]}'
    reply = app_client.post(
        "/v1/robots/robot-1/plan", content=raw, headers={"content-type": "application/json"}
    )
    assert reply.status_code == 422
    assert_detail(_plan(app_client, [0.0, 0.0], [1.0, 0.0], threshold=5.0), 422, "threshold")


def test_unknown_robot_is_404(app_client: TestClient, model_id: str) -> None:
    reply = app_client.post("/v1/robots/ghost/plan", json={"start": [0, 0], "goal": [1, 0]})
    assert_detail(reply, 404, "ghost")


def test_every_plan_call_records_an_event(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    _store(app_client, model_id, PATH)
    _plan(app_client, [0.0, 0.0], [1.0, 0.0])
    _plan(app_client, [0.0, 0.5], [1.0, 0.0])
    with ctx_of(app_client).sessions() as session:
        events = session.execute(sa.select(PlanEvent).order_by(PlanEvent.id)).scalars().all()
    assert [(e.status, e.source) for e in events] == [("success", "cache"), ("miss", None)]
    assert events[0].robot_id == "robot-1" and events[0].candidates_tried == 1


def test_concurrent_plans_and_writes_keep_the_index_consistent(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    _store(app_client, model_id, PATH)
    errors: list[str] = []

    def planner() -> None:
        for _ in range(15):
            reply = _plan(app_client, [0.0, 0.0], [1.0, 0.0])
            if reply.status_code != 200 or reply.json()["source"] != "cache":
                errors.append(reply.text)

    def writer(k: int) -> None:
        for i in range(15):
            elbow = -1.0 + 0.01 * (k * 15 + i)
            reply = app_client.post(
                "/v1/trajectories",
                json={"model_id": model_id, "states": [[0.0, elbow], [0.3, elbow]]},
            )
            if reply.status_code not in (200, 201):
                errors.append(reply.text)

    threads = [threading.Thread(target=planner) for _ in range(4)]
    threads += [threading.Thread(target=writer, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors[:3]
    ctx = ctx_of(app_client)
    with ctx.sessions() as session:
        rows = set(session.execute(sa.select(Trajectory.id)).scalars())
        model = ctx.models.get(model_id)
        assert model is not None
        index = ctx.indexes.index(session, model)
    assert set(index.ids().tolist()) == rows


@pytest.mark.parametrize(("rules_on", "expected"), [(True, "door_at_30"), (False, "nearest")])
def test_ranking_serves_the_candidate_recorded_in_the_nearest_environment(
    client_factory: Any, rules_on: bool, expected: str
) -> None:
    client = client_factory(
        ranking_env_enabled=rules_on,
        ranking_real_enabled=rules_on,
        ranking_failure_enabled=rules_on,
    )
    model_id = register(client)["model_id"]
    assert client.put("/v1/robots/robot-1", json={"model_id": model_id}).status_code == 201
    scene = {"objects": [], "env": {"door": 30.0}}
    assert client.put("/v1/robots/robot-1/scene", json=scene).status_code == 200
    ids = {
        # Nearest to the request, but recorded with the door far from today's 30°.
        "nearest": _stored(client, model_id, [[0.0, 0.0], [1.0, 0.0]], {"door": 90.0}),
        # 0.02 rad further (less than the env penalty, 0.05), recorded with the door at 30°.
        "door_at_30": _stored(client, model_id, [[0.02, 0.0], [1.0, 0.0]], {"door": 30.0}),
    }
    body = _plan(client, [0.0, 0.0], [1.0, 0.0]).json()
    assert body["status"] == "success" and body["source"] == "cache"
    assert body["trajectory_id"] == ids[expected], (body, ids)


def _stored(client: TestClient, model_id: str, states: list[list[float]], env: Any) -> int:
    body = {"model_id": model_id, "states": states, "env": env}
    reply = client.post("/v1/trajectories", json=body)
    assert reply.status_code in (200, 201), reply.text
    return int(reply.json()["trajectory_id"])
