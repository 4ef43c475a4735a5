"""Fallback planning through the API: a miss is planned in the worker pool, stored, then reused."""

from __future__ import annotations

import math
import sys
import threading
import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, ctx_of, register
from tests.conftest import REDIS_URL, require_service
from tests.waiting import SOLVABLE
from trajcache.db.models import PlanEvent
from trajcache.geometry.validation.validator import validator_for
from trajcache.jobs.backend import Meanwhile, run_meanwhile
from trajcache.jobs.pool import PlannerPool
from trajcache.planning.problem import PlannerStatus, PlanningProblem, PlanResult
from trajcache.services.catalog.models import get_model
from trajcache.services.catalog.robots import current_scene

START, GOAL = [0.0, 0.0], [1.0, 0.0]


def _box(oid: str, radius: float, angle: float, size: float) -> dict[str, Any]:
    """A cube centred `radius` from the shoulder along the arm's line at shoulder `angle`."""
    position = [radius * math.sin(angle), 0.0, 0.1 + radius * math.cos(angle)]
    return {"id": oid, "type": "box", "size": [size] * 3, "pose": {"position": position}}


# In the forearm's sweep at shoulder 0.5 with a straight elbow: bending the elbow avoids it.
DETOUR_SCENE = {"objects": [_box("bucket", 0.44, 0.5, 0.04)]}
# In the upper arm's sweep at shoulder 0.5: no elbow angle gets past, so GOAL is unreachable.
WALL_SCENE = {"objects": [_box("wall", 0.2, 0.5, 0.08)]}


def _setup(client: TestClient, scene: dict[str, Any]) -> None:
    model_id = register(client)["model_id"]
    assert client.put("/v1/robots/r1", json={"model_id": model_id}).status_code == 201
    assert client.put("/v1/robots/r1/scene", json=scene).status_code == 200


def _plan(client: TestClient, **options: Any) -> Any:
    reply = client.post("/v1/robots/r1/plan", json={"start": START, "goal": GOAL, **options})
    assert reply.status_code == 200, reply.text
    return reply.json()


def _assert_safe(client: TestClient, states: list[list[float]]) -> None:
    """The answered path passes the certified validator in the robot's current scene."""
    ctx = ctx_of(client)
    with ctx.sessions() as session:
        robot, scene, _ = current_scene(session=session, scenes=ctx.scenes, robot_id="r1")
        model = get_model(session=session, registry=ctx.models, model_id=robot.model_id)
    path = np.asarray(states)
    assert np.allclose(path[[0, -1]], [START, GOAL])
    assert validator_for(model, scene, ctx.settings, cache=ctx.validators).validate(path).valid


def _events(client: TestClient) -> list[PlanEvent]:
    with ctx_of(client).sessions() as session:
        return list(session.execute(sa.select(PlanEvent).order_by(PlanEvent.id)).scalars())


class _RecordingBackend:
    """A planner backend in process: answers the straight path, keeps the problems it got."""

    def __init__(self) -> None:
        self.problems: list[PlanningProblem] = []
        self.answer: PlanResult | None = None  # instead of the straight path

    def run(
        self, problem: PlanningProblem, timeout_s: float, meanwhile: Meanwhile | None = None
    ) -> PlanResult:
        self.problems.append(problem)
        run_meanwhile(meanwhile)
        if self.answer is not None:
            return self.answer
        path = np.array([problem.start, problem.goal])
        return PlanResult(PlannerStatus.SOLVED, path, seed=problem.seed)

    def close(self) -> None:
        pass

    def counters(self) -> dict[str, int]:
        return {}


def _recording(client: TestClient) -> _RecordingBackend:
    """Plan `client`'s misses with a _RecordingBackend."""
    backend = _RecordingBackend()
    ctx_of(client).planner = PlannerPool(backend, negative_cache_ttl_s=0.0)
    return backend


def test_miss_is_planned_stored_and_then_served_from_cache(client_factory: ClientFactory) -> None:
    client = client_factory(worker_processes=1, **SOLVABLE)
    _setup(client, DETOUR_SCENE)
    body = _plan(client)
    assert (body["status"], body["source"]) == ("success", "planner"), body
    _assert_safe(client, body["states"])
    timings = body["timings_ms"]
    assert timings["plan"] > 0
    phases = ("setup", "search", "simplify", "certify", "repair")
    assert all(timings[k] >= 0 for k in phases) and timings["search"] > 0, timings
    assert sum(timings[k] for k in phases) <= timings["worker"] <= timings["plan"], timings

    stored = client.get(f"/v1/trajectories/{body['trajectory_id']}").json()
    scene_hash = client.get("/v1/robots/r1/scene").json()["hash"]
    assert stored["source"] == "planner" and stored["scene_hash"] == scene_hash
    assert stored["robot_id"] == "r1"

    again = _plan(client)
    assert (again["status"], again["source"]) == ("success", "cache")
    assert again["trajectory_id"] == body["trajectory_id"]
    events = _events(client)
    assert [(e.source, e.trajectory_id) for e in events] == [
        ("planner", body["trajectory_id"]),
        ("cache", body["trajectory_id"]),
    ]
    assert events[0].plan_ms is not None and events[0].plan_ms > 0
    assert events[1].plan_ms == 0


def test_unreachable_goal_fails_within_budget_then_fails_fast(
    client_factory: ClientFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    client = client_factory(worker_processes=1, negative_cache_ttl_s=60)
    _setup(client, WALL_SCENE)
    pool = ctx_of(client).planner_pool()
    budgets: list[float] = []  # the budget of each problem given to the pool
    submit = pool.submit
    monkeypatch.setattr(
        pool, "submit", lambda p, **kw: budgets.append(p.budget_s) or submit(p, **kw)
    )
    body = _plan(client, options={"budget_s": 0.5})
    assert body["status"] == "failure" and body["states"] is None
    assert "timeout" in body["message"]
    assert budgets == [0.5]  # the pool holds the planner to the request's budget

    again = _plan(client, options={"budget_s": 0.5})
    assert again["status"] == "failure" and "negative cache" in again["message"]
    stats = pool.stats()
    assert (stats.completed, stats.negative_hits) == (1, 1)  # answered without planning
    assert [e.status for e in _events(client)] == ["failure", "failure"]
    assert client.get("/v1/trajectories").json()["items"] == []


def test_concurrent_identical_misses_plan_once(client_factory: ClientFactory) -> None:
    client = client_factory(worker_processes=1, **SOLVABLE)
    _setup(client, DETOUR_SCENE)
    pool = ctx_of(client).planner_pool()
    assert pool is not None
    replies: list[Any] = []

    def ask() -> None:
        replies.append(client.post("/v1/robots/r1/plan", json={"start": START, "goal": GOAL}))

    threads = [threading.Thread(target=ask) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    bodies = [r.json() for r in replies]
    assert all(r.status_code == 200 for r in replies)
    assert {(b["status"], b["source"]) for b in bodies} <= {
        ("success", "planner"),
        ("success", "cache"),  # a request that arrived after the plan was stored
    }
    assert len({b["trajectory_id"] for b in bodies}) == 1
    stats = pool.stats()
    assert stats.completed == 1, stats
    assert len(client.get("/v1/trajectories").json()["items"]) == 1


def test_fallback_off_or_planning_off_is_a_miss(client_factory: ClientFactory) -> None:
    client = client_factory()
    _setup(client, DETOUR_SCENE)
    body = _plan(client, options={"fallback": False})
    assert body["status"] == "miss" and "fallback planning disabled" in body["message"]
    assert ctx_of(client).planner is None  # no workers were started for it

    off = client_factory(worker_backend="none")
    assert ctx_of(off).planner_pool() is None
    off_body = off.post("/v1/robots/r1/plan", json={"start": START, "goal": GOAL}).json()
    assert off_body["status"] == "miss" and "planning is off" in off_body["message"]


def test_each_plan_gets_a_fresh_seed_recorded_in_its_event(
    client_factory: ClientFactory,
) -> None:
    client = client_factory()
    _setup(client, {"objects": []})
    backend = _recording(client)
    fresh = [_plan(client, options={"lookup": False}) for _ in range(3)]
    assert [b["source"] for b in fresh] == ["planner"] * 3
    hit = _plan(client)
    assert hit["source"] == "cache"
    seeds = [p.seed for p in backend.problems]
    assert len(set(seeds)) == 3 and all(1 <= s < 2**31 - 1 for s in seeds)
    assert [e.seed for e in _events(client)] == [*seeds, None]  # a cache answer planned nothing
    items = client.get("/v1/plan-events").json()["items"]  # newest first
    assert [item["seed"] for item in items] == [None, *reversed(seeds)]


def test_the_workers_validate_with_the_service_settings(client_factory: ClientFactory) -> None:
    steps = {"step_position_m": 0.05, "step_orientation_rad": 0.03, "step_joint_rad": 0.02}
    client = client_factory(certified_validation=False, **steps)
    _setup(client, {"objects": []})
    backend = _recording(client)
    assert _plan(client)["source"] == "planner"
    (problem,) = backend.problems
    sent = {name: getattr(problem, name) for name in steps}
    assert (sent, problem.certified_validation) == (steps, False)


def test_paths_that_could_not_be_certified_are_no_timeout(client_factory: ClientFactory) -> None:
    client = client_factory()
    _setup(client, {"objects": []})
    why = "no certifiable path within the budget (4 found, none certified or repaired); last: …"
    _recording(client).answer = PlanResult(PlannerStatus.UNCERTIFIED, message=why, seed=5)
    body = _plan(client)
    assert (body["status"], body["message"]) == ("failure", f"uncertified: {why}")
    assert [(e.status, e.error, e.seed) for e in _events(client)] == [
        ("failure", f"uncertified: {why}", 5)
    ]


def test_unknown_planner_is_422(client_factory: ClientFactory) -> None:
    client = client_factory()
    _setup(client, DETOUR_SCENE)
    body = {"start": START, "goal": GOAL, "options": {"planner": "astar"}}
    assert_detail(client.post("/v1/robots/r1/plan", json=body), 422, "astar", "rrtconnect")


def test_rris_is_selectable(client_factory: ClientFactory) -> None:
    client = client_factory(worker_processes=1, **SOLVABLE)
    _setup(client, DETOUR_SCENE)
    body = _plan(client, options={"planner": "RRIS"})
    assert (body["status"], body["source"]) == ("success", "planner"), body
    _assert_safe(client, body["states"])


@pytest.mark.redis
def test_celery_worker_plans_a_miss_sent_through_the_api(
    client_factory: ClientFactory, database_url: str, tmp_path: Path
) -> None:
    """The worker reads the model and the robot's scene from the service's database."""
    from tests.jobs.test_celery import Worker

    require_service("Redis", "127.0.0.1", 6379)
    queue = f"plan-api-{uuid.uuid4().hex[:8]}"
    code = "import typer; from trajcache.cli.worker import worker; typer.run(worker)"
    command = [sys.executable, "-c", code, "--concurrency", "1", "--queues", queue]
    log = tmp_path / "worker.log"
    worker = Worker(command, queue, log, REDIS_URL, task_fn=None, database_url=database_url)
    try:
        client = client_factory(
            worker_backend="celery",
            celery_queue=queue,
            celery_broker_url=REDIS_URL,
            celery_result_backend=REDIS_URL,
            negative_cache_ttl_s=0,  # attempts before the worker is up must not be remembered
        )
        _setup(client, DETOUR_SCENE)
        worker.wait_ready()
        body = _plan(client, options={"budget_s": 5.0})
        assert (body.get("status"), body.get("source")) == ("success", "planner"), (
            body,
            worker.log_tail(),
        )
        _assert_safe(client, body["states"])
        assert "succeeded" in worker.log_tail()
        assert _plan(client)["source"] == "cache"
    finally:
        worker.stop()


def test_unreachable_planner_backend_is_a_503_and_recorded(client_factory: ClientFactory) -> None:
    client = client_factory(
        worker_backend="celery",
        celery_broker_url="redis://127.0.0.1:1/0",
        celery_result_backend="redis://127.0.0.1:1/0",
    )
    _setup(client, DETOUR_SCENE)
    budget_s = 10.0
    options = {"budget_s": budget_s}
    began = time.monotonic()
    reply = client.post(
        "/v1/robots/r1/plan", json={"start": START, "goal": GOAL, "options": options}
    )
    # Fail fast is the promise: a refused broker connection is not retried for the budget.
    assert time.monotonic() - began < budget_s
    assert_detail(reply, 503, "planning is unavailable", "worker backend unavailable")
    assert "127.0.0.1" not in reply.text  # where the broker is: for operators, not robots
    [event] = _events(client)
    assert event.status == "error" and event.error is not None
    assert "worker backend unavailable" in event.error and "127.0.0.1" in event.error


def test_a_planned_trajectory_gets_its_quality_after_the_answer(
    client_factory: ClientFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Quality and timing of a new trajectory are computed by the record writer, after the
    answer, and stored with its plan record."""
    client = client_factory()
    _setup(client, {"objects": [_box("far", 2.0, 0.0, 0.1)]})
    _recording(client)
    threads: list[str] = []
    from trajcache.services.plan import fallback

    columns = fallback.quality_columns

    def spy(*args: Any, **kwargs: Any) -> Any:
        threads.append(threading.current_thread().name)
        return columns(*args, **kwargs)

    monkeypatch.setattr(fallback, "quality_columns", spy)
    body = _plan(client)
    assert (body["status"], body["source"]) == ("success", "planner")
    assert threads and threading.current_thread().name not in threads  # not the request's
    stored = client.get(f"/v1/trajectories/{body['trajectory_id']}").json()
    assert stored["length"] == pytest.approx(1.0)
    assert stored["duration_s"] > 0 and stored["min_clearance"] > 1.0


def test_a_timing_failure_is_recorded_on_the_trajectory(
    client_factory: ClientFactory, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    from trajcache.services import quality
    from trajcache.timing import TimingError

    def fails(*args: Any, **kwargs: Any) -> Any:
        raise TimingError("toppra found no parameterization: ERR_INFEASIBLE")

    client = client_factory()
    _setup(client, {"objects": [_box("far", 2.0, 0.0, 0.1)]})
    _recording(client)
    monkeypatch.setattr(quality, "time_states", fails)
    body = _plan(client)
    assert body["status"] == "success"
    stored = client.get(f"/v1/trajectories/{body['trajectory_id']}").json()
    assert stored["duration_s"] is None and stored["length"] == pytest.approx(1.0)
    with ctx_of(client).sessions() as session:
        from trajcache.db.models import Trajectory

        details = session.get(Trajectory, body["trajectory_id"]).quality
    assert "ERR_INFEASIBLE" in details["timing"]["error"]
    assert not [r for r in caplog.records if r.exc_info], "a traceback was logged"
