"""The plan answer on the wire: PlanResponse-shaped JSON, Server-Timing, bookkeeping written."""

from __future__ import annotations

from typing import Any

import sqlalchemy as sa
from fastapi.testclient import TestClient

from tests.api.conftest import ctx_of
from trajcache.api.schemas.plan import PlanResponse
from trajcache.db.models import PlanEvent, Trajectory

PATH = [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]


def _plan(client: TestClient, start: list[float], goal: list[float]) -> Any:
    body = {"start": start, "goal": goal, "options": {"fallback": False}}
    return client.post("/v1/robots/robot-1/plan", json=body)


def test_a_hit_is_a_valid_plan_response_with_server_timing(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    reply = app_client.post("/v1/trajectories", json={"model_id": model_id, "states": PATH})
    stored = reply.json()["trajectory_id"]
    reply = _plan(app_client, [0.05, 0.02], [0.98, -0.03])
    assert reply.status_code == 200 and reply.headers["content-type"] == "application/json"
    answer = PlanResponse.model_validate(reply.json())
    assert (answer.status, answer.source, answer.trajectory_id) == ("success", "cache", stored)
    assert answer.states is not None and answer.states[0] == [0.05, 0.02]
    timing = dict(part.strip().split(";dur=") for part in reply.headers["server-timing"].split(","))
    assert {"lookup", "validate", "db", "total", "serialize"} <= set(timing)
    assert all(float(v) >= 0 for v in timing.values())
    assert float(timing["total"]) == answer.timings_ms["total"]


def test_a_miss_is_a_valid_plan_response(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    answer = PlanResponse.model_validate(_plan(app_client, [0.0, 0.5], [1.0, 0.0]).json())
    assert answer.status == "miss" and answer.states is None and answer.rejected == []


def test_the_bookkeeping_of_a_hit_is_written_when_the_request_completes(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    reply = app_client.post("/v1/trajectories", json={"model_id": model_id, "states": PATH})
    stored = reply.json()["trajectory_id"]
    for i in range(3):
        assert _plan(app_client, [0.01 * i, 0.0], [1.0, 0.0]).json()["source"] == "cache"
        with ctx_of(app_client).sessions() as session:  # no flush: the cycle waited for it
            row = session.get(Trajectory, stored)
            assert row is not None and row.hits == i + 1
            count = session.scalar(sa.select(sa.func.count()).select_from(PlanEvent))
            assert count == i + 1
