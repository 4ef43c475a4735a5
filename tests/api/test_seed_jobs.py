"""/v1/seed-jobs through the real app: validation, progress, cancel, restarts, two replicas."""

from __future__ import annotations

import threading
from datetime import datetime, timedelta
from typing import Any

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, ctx_of, register
from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.db.models import PlanEvent, SeedJob, utcnow
from trajcache.main import create_app

FAST = {
    "worker_backend": "none",  # misses end at once as `miss`: runs are quick and deterministic
    "seed_heartbeat_s": 0.1,
    "seed_poll_interval_s": 0.1,
    "seed_lease_s": 3.0,
}
SCENE = {
    "objects": [{"id": "far", "type": "sphere", "size": [0.05], "pose": {"position": [2, 2, 2]}}]
}


def queries(count: int) -> list[dict[str, Any]]:
    return [{"start": [0.0, 0.0], "goal": [0.5 + 0.0004 * k, 0.5]} for k in range(count)]


def submit(client: TestClient, model_id: str, count: int = 3, **fields: Any) -> dict[str, Any]:
    body = {"model_id": model_id, "scenes": [SCENE], "queries": queries(count), **fields}
    response = client.post("/v1/seed-jobs", json=body)
    assert response.status_code == 202, response.text
    assert response.headers["location"] == f"/v1/seed-jobs/{response.json()['job_id']}"
    job: dict[str, Any] = response.json()
    return job


def job_of(client: TestClient, job_id: int) -> dict[str, Any]:
    response = client.get(f"/v1/seed-jobs/{job_id}")
    assert response.status_code == 200, response.text
    job: dict[str, Any] = response.json()
    return job


def wait_for_job(client: TestClient, job_id: int, check: Any, timeout_s: float = 60.0) -> dict:
    """The job once `check` holds for it (polled within `timeout_s`)."""
    seen: list[dict[str, Any]] = [{}]

    def reached() -> bool:
        seen[0] = job_of(client, job_id)
        return bool(check(seen[0]))

    assert wait_until(reached, timeout_s=timeout_s), f"job {job_id} never got there: {seen[0]}"
    return seen[0]


def finished(job: dict[str, Any]) -> bool:
    return job["state"] not in ("queued", "running")


def plan_events(client: TestClient, job_id: int) -> int:
    ctx = ctx_of(client)
    ctx.records.flush()
    with ctx.sessions() as session:
        count = session.scalar(
            sa.select(sa.func.count()).where(PlanEvent.robot_id == f"seed-job-{job_id}")
        )
    return int(count or 0)


def test_a_job_runs_and_reports_progress(client_factory: ClientFactory) -> None:
    client = client_factory(**FAST)
    model_id = register(client)["model_id"]
    stored = client.post(
        "/v1/trajectories", json={"model_id": model_id, "states": [[0, 0], [0.5, 0.5]]}
    )
    assert stored.status_code == 201, stored.text
    job = submit(client, model_id, count=4, name="near and far")
    body = {
        "model_id": model_id,
        "scenes": [SCENE],
        "queries": [{"start": [0, 0], "goal": [-1, 1]}],
    }
    far = client.post("/v1/seed-jobs", json=body).json()
    assert job["state"] == "queued" and job["total"] == 4

    done = wait_for_job(client, job["job_id"], finished)
    assert done["state"] == "completed"
    assert (done["done"], done["hits"], done["planned"], done["failed"]) == (4, 4, 0, 0)
    assert done["hit_rate"] == 1.0 and done["eta_s"] is None and done["runner"] is None
    assert done["name"] == "near and far"
    missed = wait_for_job(client, far["job_id"], finished)
    assert (missed["failed"], missed["hit_rate"]) == (1, 0.0)
    assert missed["errors"][0]["index"] == 0
    assert "miss" in missed["errors"][0]["reason"]
    assert plan_events(client, job["job_id"]) == 4

    listed = client.get("/v1/seed-jobs").json()
    assert [j["job_id"] for j in listed["items"]] == [far["job_id"], job["job_id"]]
    assert listed["total"] == 2
    only = client.get("/v1/seed-jobs", params={"state": "queued"}).json()
    assert only["total"] == 0


def test_everything_is_validated_before_anything_runs(client_factory: ClientFactory) -> None:
    client = client_factory(**FAST, seed_max_queries=10)
    model_id = register(client)["model_id"]
    base = {"model_id": model_id, "scenes": [SCENE]}
    assert_detail(
        client.post("/v1/seed-jobs", json={**base, "queries": [{"start": [0], "goal": [0, 0]}]}),
        422,
        "queries[0].start has 1 values",
    )
    assert_detail(
        client.post("/v1/seed-jobs", json={**base, "queries": [{"start": [0, 0], "goal": [0, 9]}]}),
        422,
        "queries[0].goal",
        "elbow",
    )
    assert_detail(
        client.post(
            "/v1/seed-jobs",
            json={
                "model_id": model_id,
                "scenes": [SCENE, {"objects": [{"id": "x"}]}],
                "queries": queries(1),
            },
        ),
        422,
        "scenes[1]",
    )
    nan = b'{"model_id": "m", "scenes": [{}], "queries": [{"start": [0, NaN], "goal": [0, 0]}]}'
    assert_detail(
        client.post("/v1/seed-jobs", content=nan, headers={"content-type": "application/json"}),
        422,
        "body.queries[0].start[1]",
    )
    assert_detail(client.post("/v1/seed-jobs", json={**base, "querys": []}), 422, "body.querys")
    assert_detail(
        client.post(
            "/v1/seed-jobs", json={**base, "queries": queries(1), "workload": {"name": "cleaning"}}
        ),
        422,
        "either queries or a workload",
    )
    assert_detail(
        client.post("/v1/seed-jobs", json={**base, "model_id": "f" * 64, "queries": queries(1)}),
        404,
        "robot model",
    )
    assert_detail(
        client.post("/v1/seed-jobs", json={**base, "queries": queries(11)}),
        413,
        "seed_max_queries=10",
    )
    assert_detail(
        client.post("/v1/seed-jobs", json={**base, "queries": queries(1), "concurrency": 50}),
        422,
        "seed_concurrency",
    )
    assert client.get("/v1/seed-jobs").json()["total"] == 0
    assert_detail(client.get("/v1/seed-jobs/12345"), 404, "seed job 12345")
    assert_detail(client.get("/v1/seed-jobs/0"), 422, "job_id")
    assert_detail(client.get("/v1/seed-jobs", params={"state": "done"}), 422, "state")


def test_a_body_over_max_body_bytes_is_refused_while_read(client_factory: ClientFactory) -> None:
    client = client_factory(**FAST, max_body_bytes=2000)
    model_id = register(client)["model_id"]
    body = {"model_id": model_id, "scenes": [SCENE], "queries": queries(100)}
    assert_detail(client.post("/v1/seed-jobs", json=body), 413, "max_body_bytes=2000")

    def chunks() -> Any:
        yield b'{"model_id": "m", "queries": ['
        for _ in range(200):
            yield b'{"start": [0, 0], "goal": [0, 0]},'

    streamed = client.post(
        "/v1/seed-jobs", content=chunks(), headers={"content-type": "application/json"}
    )
    assert_detail(streamed, 413, "more than 2000 bytes")
    assert client.get("/v1/seed-jobs").json()["total"] == 0


def test_cancel_stops_a_running_job_promptly(client_factory: ClientFactory) -> None:
    client = client_factory(**FAST)
    model_id = register(client)["model_id"]
    job = submit(client, model_id, count=3000)
    running = wait_for_job(client, job["job_id"], lambda j: j["done"] > 0)
    assert running["state"] == "running" and running["runner"]
    assert running["eta_s"] is not None and running["eta_s"] >= 0
    assert running["started_at"] is not None and running["finished_at"] is None

    cancelled = client.delete(f"/v1/seed-jobs/{job['job_id']}")
    assert cancelled.status_code == 200, cancelled.text
    assert cancelled.json()["state"] == "cancelled"
    seeds = client.app.state.background.seeds  # type: ignore[attr-defined]
    caller = f"seed-job-{job['job_id']}"  # the run's thread and its planning threads
    assert wait_until(lambda: not any(t.name.startswith(caller) for t in threading.enumerate())), (
        "the run did not stop"
    )
    events = plan_events(client, job["job_id"])
    assert job["job_id"] not in seeds.running() + seeds.poll()  # not run again
    assert plan_events(client, job["job_id"]) == events  # nothing new was started
    assert events < 3000
    after = job_of(client, job["job_id"])
    assert after["state"] == "cancelled" and after["done"] < 3000
    assert after["finished_at"] is not None and after["runner"] is None

    again = client.delete(f"/v1/seed-jobs/{job['job_id']}")
    assert again.status_code == 200 and again.json()["state"] == "cancelled"
    small = submit(client, model_id, count=1)
    wait_for_job(client, small["job_id"], finished)
    assert_detail(client.delete(f"/v1/seed-jobs/{small['job_id']}"), 409, "already completed")
    assert_detail(client.delete("/v1/seed-jobs/999"), 404)


def test_a_restarted_service_resumes_where_it_stopped(database_url: str) -> None:
    settings = Settings(database_url=database_url, **FAST)  # type: ignore[arg-type]
    with TestClient(create_app(settings)) as first:
        model_id = register(first)["model_id"]
        job = submit(first, model_id, count=400)
        wait_for_job(first, job["job_id"], lambda j: j["done"] > 0)
    # A graceful stop waits for the requests in flight and hands the job back.
    with TestClient(create_app(settings)) as second:
        ctx = ctx_of(second)
        with ctx.sessions() as session:
            row = session.get(SeedJob, job["job_id"])
            assert row is not None
        handed_back = row.done
        assert 0 < handed_back < 400
        assert plan_events(second, job["job_id"]) == handed_back
        done = wait_for_job(second, job["job_id"], finished)
    assert (done["state"], done["done"], done["failed"]) == ("completed", 400, 400)
    with TestClient(create_app(settings)) as third:
        assert plan_events(third, job["job_id"]) == 400  # every request planned exactly once


def test_the_handed_back_state_is_queued_without_a_lease(database_url: str) -> None:
    settings = Settings(database_url=database_url, **FAST)  # type: ignore[arg-type]
    with TestClient(create_app(settings)) as client:
        model_id = register(client)["model_id"]
        job = submit(client, model_id, count=400)
        wait_for_job(client, job["job_id"], lambda j: j["done"] > 0)
        ctx = ctx_of(client)
        client.app.state.background.seeds.stop()  # type: ignore[attr-defined]
        with ctx.sessions() as session:
            row = session.get(SeedJob, job["job_id"])
            assert row is not None
            assert (row.state, row.lease_owner, row.lease_expires_at) == ("queued", None, None)
            assert 0 < row.done < 400


@pytest.mark.parametrize("stop_the_runner", [False, True])
def test_two_replicas_never_run_one_job_together(database_url: str, stop_the_runner: bool) -> None:
    settings = Settings(database_url=database_url, **FAST)  # type: ignore[arg-type]
    with TestClient(create_app(settings)) as a, TestClient(create_app(settings)) as b:
        model_id = register(a)["model_id"]
        seeds = [c.app.state.background.seeds for c in (a, b)]  # type: ignore[attr-defined]
        job = submit(a, model_id, count=300)
        both: list[bool] = []
        watching = threading.Event()

        def watch() -> None:
            while not watching.is_set():
                both.append(all(job["job_id"] in s.running() for s in seeds))
                watching.wait(0.005)  # sample every 5 ms until told to stop

        watcher = threading.Thread(target=watch)
        watcher.start()
        try:
            running = wait_for_job(a, job["job_id"], lambda j: j["done"] > 0)
            runner = next(s for s in seeds if s.owner == running["runner"])
            if stop_the_runner:  # the other replica takes the job over and finishes it
                runner.stop()
            done = wait_for_job(b, job["job_id"], finished)
        finally:
            watching.set()
            watcher.join()
        assert done["state"] == "completed" and done["done"] == 300
        assert not any(both)
        ctx_of(b).records.flush()  # the events b wrote (plan_events flushes a's)
        assert plan_events(a, job["job_id"]) == 300
        if stop_the_runner:
            other = next(s for s in seeds if s is not runner)
            assert done["started_at"] is not None and other.owner != runner.owner


def test_robot_kind_real_or_sim(client_factory: ClientFactory) -> None:
    client = client_factory(**FAST)
    model_id = register(client)["model_id"]
    created = client.put("/v1/robots/sim-1", json={"model_id": model_id, "kind": "sim"})
    assert created.status_code == 201 and created.json()["kind"] == "sim"
    default = client.put("/v1/robots/real-1", json={"model_id": model_id})
    assert default.json()["kind"] == "real"
    kept = client.put("/v1/robots/sim-1", json={"model_id": model_id})
    assert kept.status_code == 200 and kept.json()["kind"] == "sim"
    changed = client.put("/v1/robots/sim-1", json={"model_id": model_id, "kind": "real"})
    assert changed.json()["kind"] == "real"
    assert client.get("/v1/robots/sim-1").json()["kind"] == "real"
    assert_detail(
        client.put("/v1/robots/r", json={"model_id": model_id, "kind": "robotic"}), 422, "body.kind"
    )


def test_a_running_job_whose_lease_ran_out_is_shown_stale(database_url: str) -> None:
    settings = Settings(database_url=database_url, **FAST)  # type: ignore[arg-type]
    with TestClient(create_app(settings)) as client:
        model_id = register(client)["model_id"]
        client.app.state.background.seeds.stop()  # type: ignore[attr-defined]
        job_id = submit(client, model_id)["job_id"]  # queued: this replica no longer runs jobs
        assert (job_of(client, job_id)["lease_expires_at"], job_of(client, job_id)["stale"]) == (
            None,
            False,
        )
        now = utcnow()
        for lease_ends, stale in ((now + timedelta(minutes=1), False), (now, True)):
            with ctx_of(client).sessions() as session:  # a replica that holds the job, or held it
                session.execute(
                    sa.update(SeedJob)
                    .where(SeedJob.id == job_id)
                    .values(state="running", lease_owner="gone:1", lease_expires_at=lease_ends)
                )
                session.commit()
            job = job_of(client, job_id)
            assert (job["state"], job["runner"], job["stale"]) == ("running", "gone:1", stale)
            assert datetime.fromisoformat(job["lease_expires_at"]) == lease_ends
