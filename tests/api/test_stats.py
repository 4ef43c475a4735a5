"""GET /v1/stats, /v1/stats/top-trajectories, /v1/plan-events and trajectory usage history."""

from __future__ import annotations

import base64
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, ctx_of
from trajcache.db.models import PlanEvent
from trajcache.services.catalog.keys import create_key

PATH = [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]
OTHER = [[0.0, -1.0], [0.4, -1.0]]
# (hours ago, source, planning ms) of events written directly, as earlier hours' traffic.
EARLIER = [
    (30, "planner", 80.0),
    (20, "planner", 120.0),
    (5, "cache", 0.0),
    (4, "planner", 100.0),
    (3, "cache", 0.0),
]


def _store(client: TestClient, model_id: str, states: list[list[float]]) -> int:
    reply = client.post("/v1/trajectories", json={"model_id": model_id, "states": states})
    assert reply.status_code in (200, 201), reply.text
    return int(reply.json()["trajectory_id"])


def _plan(client: TestClient, robot: str, start: list[float], goal: list[float]) -> Any:
    body = {"start": start, "goal": goal, "options": {"fallback": False}}
    reply = client.post(f"/v1/robots/{robot}/plan", json=body)
    assert reply.status_code == 200, reply.text
    return reply.json()


@pytest.fixture
def fleet(app_client: TestClient, model_id: str) -> dict[str, Any]:
    """Two robots of one model; r1 gets 3 hits and 1 miss, r2 gets 2 hits (real plan calls)."""
    for robot in ("r1", "r2"):
        assert app_client.put(f"/v1/robots/{robot}", json={"model_id": model_id}).status_code == 201
    path_id = _store(app_client, model_id, PATH)
    other_id = _store(app_client, model_id, OTHER)
    answers = [
        _plan(app_client, "r1", [0.0, 0.0], [1.0, 0.0]),
        _plan(app_client, "r1", [0.02, 0.01], [0.98, 0.0]),
        _plan(app_client, "r1", [1.0, 0.0], [0.0, 0.0]),  # reversed: still a hit
        _plan(app_client, "r1", [0.0, 0.9], [1.0, 0.9]),  # nothing near: a miss
        _plan(app_client, "r2", [0.0, 0.0], [1.0, 0.0]),
        _plan(app_client, "r2", [0.0, -1.0], [0.4, -1.0]),
    ]
    assert [a["source"] for a in answers] == ["cache"] * 3 + [None] + ["cache"] * 2
    return {"model_id": model_id, "path_id": path_id, "other_id": other_id, "answers": answers}


def test_stats_of_real_plan_calls(app_client: TestClient, fleet: dict[str, Any]) -> None:
    body = app_client.get("/v1/stats", params={"window": "1h"}).json()
    totals = body["totals"]
    assert (totals["requests"], totals["hits"], totals["misses"]) == (6, 5, 1)
    assert (totals["planner_calls"], totals["failures"]) == (0, 0)
    assert totals["hit_rate"] == pytest.approx(5 / 6)
    lookups = [a["timings_ms"]["lookup"] for a in fleet["answers"]]
    assert totals["lookup_ms"]["sum_ms"] == pytest.approx(sum(lookups), abs=1e-6)
    assert 0 < totals["validate_ms"]["p50"] <= totals["validate_ms"]["p99"]
    assert totals["plan_ms"]["p50"] is None  # no planner call
    # No planner call in the window: the hits have no estimate and are not credited.
    assert totals["time_saved_ms"] == 0 and totals["uncredited_hits"] == 5
    assert body["time_saved_basis"] == [
        {"model_id": fleet["model_id"], "hits": 5, "planner_calls": 0, "median_plan_ms": None}
    ]
    groups = {g["key"]: g for g in body["groups"]}
    assert (groups["r1"]["requests"], groups["r1"]["hits"]) == (4, 3)
    assert (groups["r2"]["requests"], groups["r2"]["hits"]) == (2, 2)
    assert [g["key"] for g in body["groups"]] == ["r1", "r2"]  # busiest first
    # the series spans the data (a few seconds, so the last minute), not the whole hour
    assert body["bucket_s"] == 5 and body["window"] == "1h" and body["group_by"] == "robot"
    assert sum(b["requests"] for b in body["series"]) == 6
    assert 12 <= len(body["series"]) <= 13
    assert body["percentile_max_relative_error"] == pytest.approx(0.0593, abs=1e-3)


def test_group_by_source_and_model_and_filters(
    app_client: TestClient, fleet: dict[str, Any]
) -> None:
    by_source = app_client.get("/v1/stats", params={"window": "1h", "group_by": "source"}).json()
    assert {g["key"]: g["requests"] for g in by_source["groups"]} == {"cache": 5, "none": 1}
    by_model = app_client.get("/v1/stats", params={"group_by": "model"}).json()
    assert [(g["key"], g["requests"]) for g in by_model["groups"]] == [(fleet["model_id"], 6)]
    assert by_model["window"] == "24h" and by_model["bucket_s"] == 5
    only = app_client.get("/v1/stats", params={"robot_id": "r2"}).json()
    assert only["totals"]["requests"] == 2
    none = app_client.get("/v1/stats", params={"model_id": "nope"}).json()
    assert none["totals"]["requests"] == 0 and none["totals"]["hit_rate"] is None


def test_long_windows_read_rollups_and_count_time_saved(
    app_client: TestClient, fleet: dict[str, Any]
) -> None:
    """Events of earlier hours (planner calls among them) enter the 7-day statistics."""
    now = datetime.now(UTC)
    model_id = fleet["model_id"]
    rows = [
        PlanEvent(
            created_at=now - timedelta(hours=h, minutes=7),
            robot_id="r1",
            model_id=model_id,
            status="success",
            source=source,
            trajectory_id=fleet["path_id"],
            lookup_ms=0.3,
            validate_ms=4.0,
            plan_ms=plan_ms,
            total_ms=5.0 + plan_ms,
        )
        for h, source, plan_ms in EARLIER
    ]
    with ctx_of(app_client).sessions() as session:
        session.add_all(rows)
        session.commit()
    body = app_client.get("/v1/stats", params={"window": "7d"}).json()
    totals = body["totals"]
    assert body["bucket_s"] == 3600
    assert (totals["requests"], totals["hits"], totals["planner_calls"]) == (11, 7, 3)
    median = body["time_saved_basis"][0]["median_plan_ms"]
    assert median == pytest.approx(100.0, rel=0.06)
    assert totals["time_saved_ms"] == pytest.approx(7 * median)
    assert totals["uncredited_hits"] == 0
    assert totals["plan_ms"]["sum_ms"] == pytest.approx(300.0)
    assert sum(b["requests"] for b in body["series"]) == 11
    one_day = app_client.get("/v1/stats", params={"window": "1d"}).json()["totals"]
    assert (one_day["requests"], one_day["planner_calls"]) == (10, 2)


@pytest.mark.parametrize(
    ("params", "needle"),
    [
        ({"window": "2w"}, "query.window"),
        ({"window": "0m"}, "query.window"),
        ({"window": "400d"}, "query.window"),
        ({"window": "soon"}, "query.window"),
        ({"window": "x" * 40}, "window"),
        ({"group_by": "scene"}, "group_by"),
        ({"requester": "drone"}, "requester"),
        ({"robot_id": "r" * 200}, "robot_id"),
    ],
)
def test_bad_stats_queries_are_422(
    app_client: TestClient, params: dict[str, str], needle: str
) -> None:
    assert_detail(app_client.get("/v1/stats", params=params), 422, needle)


def test_a_seed_job_and_a_robot_of_the_same_name_stay_apart(
    app_client: TestClient, fleet: dict[str, Any]
) -> None:
    """Grouped by robot, the pair (robot id, requester) is the group, in events and rollups."""
    now = datetime.now(UTC)
    # (minutes ago, requester): this hour's events and events of hours already rolled up
    written = [(m, "seed_job") for m in (2, 3, 4, 190, 200)] + [(m, "robot") for m in (5, 210)]
    with ctx_of(app_client).sessions() as session:
        session.add_all(
            PlanEvent(
                created_at=now - timedelta(minutes=m),
                robot_id="seed-job-1",
                requester=requester,
                model_id=fleet["model_id"],
                status="miss",
                lookup_ms=0.2,
                validate_ms=1.0,
                plan_ms=0.0,
                total_ms=1.5,
            )
            for m, requester in written
        )
        session.commit()
    for window, seed_job, robot in (("1h", 3, 1), ("7d", 5, 2)):  # 7d: from the rollups
        body = app_client.get("/v1/stats", params={"window": window}).json()
        groups = {(g["key"], g["requester"]): g["requests"] for g in body["groups"]}
        assert groups == {
            ("r1", "robot"): 4,
            ("r2", "robot"): 2,
            ("seed-job-1", "seed_job"): seed_job,
            ("seed-job-1", "robot"): robot,
        }, window
        only = {"window": window, "requester": "seed_job"}
        assert app_client.get("/v1/stats", params=only).json()["totals"]["requests"] == seed_job
        robots = {"window": window, "requester": "robot"}
        assert app_client.get("/v1/stats", params=robots).json()["totals"]["requests"] == 6 + robot
    by_model = app_client.get("/v1/stats", params={"group_by": "model"}).json()["groups"]
    assert [g["requester"] for g in by_model] == [None]
    events = _all_pages(app_client, limit=100)
    assert {e["requester"] for e in events if e["robot_id"] != "seed-job-1"} == {"robot"}
    seed_events = _all_pages(app_client, requester="seed_job")
    assert len(seed_events) == 5
    assert {(e["robot_id"], e["requester"]) for e in seed_events} == {("seed-job-1", "seed_job")}
    assert len(_all_pages(app_client, requester="robot", robot_id="seed-job-1")) == 2
    assert_detail(app_client.get("/v1/plan-events", params={"requester": "x"}), 422, "requester")


def _cursor(text: str) -> str:
    return base64.urlsafe_b64encode(text.encode()).decode()


def _all_pages(client: TestClient, **params: Any) -> list[dict[str, Any]]:
    items: list[dict[str, Any]] = []
    cursor = None
    while True:
        query = {**params, **({"cursor": cursor} if cursor else {})}
        page = client.get("/v1/plan-events", params=query)
        assert page.status_code == 200, page.text
        body = page.json()
        assert len(body["items"]) <= body["limit"]
        items += body["items"]
        cursor = body["next_cursor"]
        if cursor is None:
            return items


def test_plan_events_filters_and_cursor_pages(
    app_client: TestClient, fleet: dict[str, Any]
) -> None:
    everything = _all_pages(app_client, limit=100)
    assert len(everything) == 6
    paged = _all_pages(app_client, limit=4)
    assert [e["event_id"] for e in paged] == [e["event_id"] for e in everything]
    assert [e["created_at"] for e in everything] == sorted(
        (e["created_at"] for e in everything), reverse=True
    )
    one = _all_pages(app_client, limit=1)
    assert [e["event_id"] for e in one] == [e["event_id"] for e in everything]
    assert {e["robot_id"] for e in _all_pages(app_client, robot_id="r2")} == {"r2"}
    misses = _all_pages(app_client, status="miss")
    assert len(misses) == 1 and misses[0]["source"] is None
    assert misses[0]["error"].startswith("no valid cached trajectory")
    assert len(_all_pages(app_client, source="none")) == 1
    assert len(_all_pages(app_client, source="cache", robot_id="r1")) == 3
    served = _all_pages(app_client, trajectory_id=fleet["path_id"])
    assert len(served) == 4 and all(e["trajectory_id"] == fleet["path_id"] for e in served)
    assert _all_pages(app_client, model_id="nope") == []
    middle = everything[2]["created_at"]
    newer = _all_pages(app_client, since=middle)
    older = _all_pages(app_client, until=middle)
    assert len(newer) + len(older) == 6 and all(e["created_at"] < middle for e in older)
    wide = _all_pages(app_client, since="0001-01-01T00:00:00", until="9999-12-31T23:59:59Z")
    assert len(wide) == 6  # a time without an offset is UTC
    for number in ("1700000000", "2.5e-194", " -3 "):  # not read as Unix times
        reply = app_client.get("/v1/plan-events", params={"since": number})
        assert_detail(reply, 422, "query.since", "not an ISO 8601 date and time")


def test_plan_event_pages_do_not_shift_when_events_arrive(
    app_client: TestClient, fleet: dict[str, Any]
) -> None:
    first = app_client.get("/v1/plan-events", params={"limit": 3}).json()
    _plan(app_client, "r2", [0.0, 0.0], [1.0, 0.0])  # a new event, newer than every page
    second = app_client.get("/v1/plan-events", params={"limit": 3, "cursor": first["next_cursor"]})
    ids = [e["event_id"] for e in first["items"] + second.json()["items"]]
    assert len(ids) == len(set(ids)) == 6
    assert sorted(ids, reverse=True) == ids


@pytest.mark.parametrize(
    ("params", "needle"),
    [
        ({"cursor": "not-a-cursor"}, "query.cursor"),
        ({"cursor": "MTIz"}, "query.cursor"),  # base64 of "123": no id
        ({"cursor": _cursor("1:99999999999999999999")}, "query.cursor"),  # id beyond BIGINT
        ({"cursor": _cursor("99999999999999999999:5")}, "query.cursor"),  # time beyond year 9999
        ({"cursor": _cursor("1:-4")}, "query.cursor"),
        ({"limit": 5000}, "query.limit"),
        ({"limit": 0}, "limit"),
        ({"status": "great"}, "status"),
        ({"source": "sim"}, "source"),
        ({"since": "yesterday"}, "since"),
        ({"since": "2026-01-02T00:00:00Z", "until": "2026-01-01T00:00:00Z"}, "since"),
        ({"trajectory_id": 0}, "trajectory_id"),
    ],
)
def test_bad_plan_event_queries_are_422(
    app_client: TestClient, params: dict[str, Any], needle: str
) -> None:
    assert_detail(app_client.get("/v1/plan-events", params=params), 422, needle)


def test_trajectory_detail_has_its_usage_history(
    app_client: TestClient, fleet: dict[str, Any]
) -> None:
    body = app_client.get(f"/v1/trajectories/{fleet['path_id']}").json()
    history = body["usage_history"]
    assert len(history) == 4 and {e["robot_id"] for e in history} == {"r1", "r2"}
    assert all(e["trajectory_id"] == fleet["path_id"] and e["source"] == "cache" for e in history)
    assert [e["event_id"] for e in history] == sorted(
        (e["event_id"] for e in history), reverse=True
    )
    assert body["states"] == PATH and body["hits"] == 4
    fresh = _store(app_client, fleet["model_id"], [[0.3, 0.3], [0.6, 0.6]])
    assert app_client.get(f"/v1/trajectories/{fresh}").json()["usage_history"] == []


def test_top_trajectories_by_hits(app_client: TestClient, fleet: dict[str, Any]) -> None:
    top = app_client.get("/v1/stats/top-trajectories", params={"limit": 5}).json()
    assert [(t["trajectory_id"], t["hits"]) for t in top] == [
        (fleet["path_id"], 4),
        (fleet["other_id"], 1),
    ]
    assert "states" not in top[0]
    assert app_client.get("/v1/stats/top-trajectories", params={"model_id": "nope"}).json() == []
    assert_detail(app_client.get("/v1/stats/top-trajectories", params={"limit": 500}), 422, "limit")


def test_statistics_are_for_admin_keys_only(client_factory: ClientFactory) -> None:
    client = client_factory(auth_mode="on")
    with ctx_of(client).sessions() as session:
        _, admin = create_key(session=session, name="ops", role="admin")
        _, seeder = create_key(session=session, name="farm", role="seeder")
    assert client.get("/v1/stats").status_code == 401
    assert client.get("/v1/plan-events").status_code == 401
    for path in ("/v1/stats", "/v1/plan-events", "/v1/stats/top-trajectories"):
        denied = client.get(path, headers={"Authorization": f"Bearer {seeder}"})
        assert_detail(denied, 403, "admin only")
        assert client.get(path, headers={"Authorization": f"Bearer {admin}"}).status_code == 200
