"""GET /metrics: plan counters and latencies, cache size, the planner pool, several processes."""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from prometheus_client import multiprocess
from prometheus_client.parser import text_string_to_metric_families

from tests.api.conftest import ClientFactory, ctx_of, register
from tests.jobs.test_pool import make_local_pool, make_problem
from tests.robots import TWO_JOINT_URDF
from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.core.prometheus_dir import MULTIPROC_ENV, prepare_multiprocess_dir
from trajcache.main import create_app

PATH = [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]
GRAFANA = Path(__file__).resolve().parents[2] / "docker" / "grafana-dashboard.json"


def samples(text: str) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    """Every sample of an exposition, by name and sorted labels."""
    out: dict[tuple[str, tuple[tuple[str, str], ...]], float] = {}
    for family in text_string_to_metric_families(text):
        for s in family.samples:
            out[(s.name, tuple(sorted(s.labels.items())))] = s.value
    return out


def value(scrape: dict[Any, float], name: str, **labels: str) -> float:
    return scrape.get((name, tuple(sorted(labels.items()))), 0.0)


def scrape(client: TestClient | httpx.Client) -> dict[Any, float]:
    reply = client.get("/metrics")
    assert reply.status_code == 200, reply.text
    assert reply.headers["content-type"].startswith("text/plain")
    return samples(reply.text)


def _plan(client: TestClient, start: list[float], goal: list[float]) -> dict[str, Any]:
    body = {"start": start, "goal": goal, "options": {"fallback": False}}
    reply = client.post("/v1/robots/robot-1/plan", json=body)
    assert reply.status_code == 200, reply.text
    answer: dict[str, Any] = reply.json()
    return answer


def test_plan_requests_latencies_and_cache_size(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    for states in (PATH, [[0.0, -1.0], [0.3, -1.0]]):
        reply = app_client.post("/v1/trajectories", json={"model_id": model_id, "states": states})
        assert reply.status_code == 201
    before = scrape(app_client)
    answers = [_plan(app_client, [0.0, 0.0], [1.0, 0.0]) for _ in range(3)]
    answers.append(_plan(app_client, [0.0, 0.9], [1.0, 0.9]))  # a miss
    after = scrape(app_client)

    def delta(name: str, **labels: str) -> float:
        return value(after, name, **labels) - value(before, name, **labels)

    robot = {"requester": "robot"}
    hits = delta("trajcache_plan_requests_total", source="cache", status="success", **robot)
    assert hits == 3
    assert delta("trajcache_plan_requests_total", source="none", status="miss", **robot) == 1
    assert delta("trajcache_plan_lookup_seconds_count") == 4
    assert delta("trajcache_plan_validate_seconds_count") == 4
    lookup_s = sum(a["timings_ms"]["lookup"] for a in answers) / 1e3
    assert delta("trajcache_plan_lookup_seconds_sum") == pytest.approx(lookup_s, abs=1e-9)
    assert delta("trajcache_plan_planning_seconds_count") == 0  # the planner was never asked
    assert delta("trajcache_plan_total_seconds_count", source="cache", **robot) == 3
    assert delta("trajcache_plan_total_seconds_count", source="none", **robot) == 1
    top = delta("trajcache_plan_lookup_seconds_bucket", le="+Inf")
    assert top == 4
    assert value(after, "trajcache_cache_trajectories", model=model_id) == 2
    assert value(after, "trajcache_database_up") == 1
    assert ("trajcache_pool_queue_depth", ()) in after


def total(scrape: dict[Any, float], name: str, **labels: str) -> float:
    """The sum of the samples of `name` that have these labels (and any others)."""
    return sum(
        v for (n, have), v in scrape.items() if n == name and set(labels.items()) <= set(have)
    )


SEED_FAST = {
    "worker_backend": "none",  # a miss is answered at once, without planning
    "seed_heartbeat_s": 0.1,
    "seed_poll_interval_s": 0.1,
}


def test_robots_and_seed_jobs_are_counted_as_the_stats_count_them(
    client_factory: ClientFactory,
) -> None:
    """Every answered plan is counted, a seed job's too, apart by requester: as /v1/stats."""
    client = client_factory(**SEED_FAST)
    model_id = register(client)["model_id"]
    assert client.put("/v1/robots/robot-1", json={"model_id": model_id}).status_code == 201
    reply = client.post("/v1/trajectories", json={"model_id": model_id, "states": PATH})
    assert reply.status_code == 201
    before = scrape(client)
    _plan(client, [0.0, 0.0], [1.0, 0.0])
    _plan(client, [0.02, 0.01], [0.98, 0.0])
    _plan(client, [0.0, 0.9], [1.0, 0.9])  # nothing near: a miss
    queries = [
        {"start": [0.0, 0.0], "goal": [1.0, 0.0]},
        {"start": [0.01, 0.0], "goal": [1.0, 0.0]},
        {"start": [0.0, -0.9], "goal": [1.0, -0.9]},  # misses: the job's failed items
        {"start": [0.0, 0.9], "goal": [1.0, 0.9]},
    ]
    spec = {"model_id": model_id, "scenes": [{"objects": []}], "queries": queries}
    job = client.post("/v1/seed-jobs", json=spec).json()

    def ended() -> bool:
        return client.get(f"/v1/seed-jobs/{job['job_id']}").json()["state"] == "completed"

    assert wait_until(ended, timeout_s=60)
    ctx_of(client).records.flush()
    after = scrape(client)

    def delta(name: str, **labels: str) -> float:
        return total(after, name, **labels) - total(before, name, **labels)

    def stats(**params: str) -> dict[str, Any]:
        reply = client.get("/v1/stats", params={"window": "1h", **params})
        assert reply.status_code == 200, reply.text
        body: dict[str, Any] = reply.json()
        return body

    counted = delta("trajcache_plan_requests_total")
    assert counted == stats()["totals"]["requests"] == 7
    for requester, requests, hits in (("robot", 3, 2), ("seed_job", 4, 2)):
        totals = stats(requester=requester)["totals"]
        assert (totals["requests"], totals["hits"]) == (requests, hits)
        assert delta("trajcache_plan_requests_total", requester=requester) == requests
        cached = {"requester": requester, "source": "cache", "status": "success"}
        assert delta("trajcache_plan_requests_total", **cached) == hits
        assert delta("trajcache_plan_total_seconds_count", requester=requester) == requests
    groups = {(g["key"], g["requester"]): g["requests"] for g in stats()["groups"]}
    assert groups == {("robot-1", "robot"): 3, (f"seed-job-{job['job_id']}", "seed_job"): 4}


def test_the_grafana_dashboard_charts_exposed_metrics(
    app_client: TestClient, model_id: str, robot_id: str
) -> None:
    reply = app_client.post("/v1/trajectories", json={"model_id": model_id, "states": PATH})
    assert reply.status_code == 201
    _plan(app_client, [0.0, 0.0], [1.0, 0.0])
    exposed = {name for name, _ in scrape(app_client)}
    dashboard = json.loads(GRAFANA.read_text())
    exprs = [t["expr"] for p in dashboard["panels"] for t in p.get("targets", [])]
    used = {name for expr in exprs for name in re.findall(r"trajcache_[a-z_]+", expr)}
    assert len(exprs) >= 15 and len(used) >= 10
    assert used <= exposed, used - exposed


def test_pool_queue_depth_and_worker_failures(
    client_factory: ClientFactory, tmp_path: Path
) -> None:
    """A real planner pool: a run in flight shows in the queue depth, a crash in the counters."""
    client = client_factory()
    pool = make_local_pool(processes=1)
    ctx_of(client).planner = pool  # closed with the app
    before = scrape(client)
    done = threading.Event()

    def slow_run() -> None:
        pool.submit(make_problem(tmp_path, scene="slow", sleep=2.0))
        done.set()

    threading.Thread(target=slow_run, daemon=True).start()
    assert wait_until(
        lambda: value(scrape(client), "trajcache_pool_queue_depth") == 1, interval_s=0.05
    )
    assert done.wait(15)
    assert pool.submit(make_problem(tmp_path, scene="crash", exit=True)).status.value == "error"
    after = scrape(client)
    assert value(after, "trajcache_pool_queue_depth") == 0

    def delta(name: str) -> float:
        return value(after, name) - value(before, name)

    assert delta("trajcache_pool_worker_crashes_total") == 1
    assert delta("trajcache_pool_recycles_total") == 1
    assert delta("trajcache_pool_failed_runs_total") == 1


def test_metrics_stay_open_when_keys_are_required(client_factory: ClientFactory) -> None:
    client = client_factory(auth_mode="on")
    assert client.get("/v1/stats").status_code == 401
    assert value(scrape(client), "trajcache_database_up") == 1


# --- several processes ----------------------------------------------------------------------

RECORDER = """
import os
import sys
from trajcache.services.bookkeeping.metrics import POOL_QUEUE_DEPTH, record_plan

hits, depth = int(sys.argv[1]), int(sys.argv[2])
timings = {"lookup": 0.5, "validate": 4.0, "plan": 0.0, "total": 6.0}
for _ in range(hits):
    record_plan(status="success", source="cache", requester="robot", timings=timings)
planned = {**timings, "plan": 70.0, "total": 80.0}
record_plan(status="success", source="planner", requester="seed_job", timings=planned)
POOL_QUEUE_DEPTH.set(depth)
print(os.getpid())
"""


def _record_in_a_process(directory: Path, hits: int, depth: int) -> int:
    env = {**os.environ, MULTIPROC_ENV: str(directory)}
    proc = subprocess.run(
        [sys.executable, "-c", RECORDER, str(hits), str(depth)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    return int(proc.stdout)


@pytest.fixture
def sqlite_client(tmp_path: Path) -> Iterator[TestClient]:
    """The app on a SQLite file (for tests about processes, not databases)."""
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'm.db'}", worker_prestart=False)
    with TestClient(create_app(settings)) as client:
        yield client


def test_multiprocess_mode_merges_every_process(
    sqlite_client: TestClient, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    app_client = sqlite_client
    directory = tmp_path / "prometheus"
    directory.mkdir()
    first = _record_in_a_process(directory, hits=3, depth=2)
    _record_in_a_process(directory, hits=4, depth=5)
    monkeypatch.setenv(MULTIPROC_ENV, str(directory))
    reply = app_client.get("/metrics")
    merged = samples(reply.text)
    cache = {"source": "cache", "status": "success", "requester": "robot"}
    planner = {"source": "planner", "status": "success", "requester": "seed_job"}
    assert value(merged, "trajcache_plan_requests_total", **cache) == 7
    assert value(merged, "trajcache_plan_requests_total", **planner) == 2
    assert value(merged, "trajcache_plan_planning_seconds_count") == 2
    assert value(merged, "trajcache_plan_planning_seconds_sum") == pytest.approx(0.14)
    assert value(merged, "trajcache_plan_lookup_seconds_count") == 9
    assert value(merged, "trajcache_pool_queue_depth") == 7  # live processes add up
    assert value(merged, "trajcache_database_up") == 1
    names = [f.name for f in text_string_to_metric_families(reply.text)]
    assert len(names) == len(set(names))  # one family each, this process's own not mixed in
    multiprocess.mark_process_dead(first, str(directory))
    after = samples(app_client.get("/metrics").text)
    assert value(after, "trajcache_pool_queue_depth") == 5  # a finished process leaves the sum
    assert value(after, "trajcache_plan_requests_total", **cache) == 7


def test_prepare_multiprocess_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(MULTIPROC_ENV, raising=False)
    assert prepare_multiprocess_dir(1) is None and MULTIPROC_ENV not in os.environ
    made = prepare_multiprocess_dir(3)
    assert made is not None and Path(made).is_dir() and os.environ[MULTIPROC_ENV] == made
    Path(made).rmdir()
    given = tmp_path / "metrics"
    given.mkdir()
    (given / "counter_123.db").write_bytes(b"stale")
    monkeypatch.setenv(MULTIPROC_ENV, str(given))
    assert prepare_multiprocess_dir(1) == str(given)
    assert given.is_dir() and list(given.iterdir()) == []


@pytest.mark.slow
def test_every_worker_of_a_served_app_reports_every_request(tmp_path: Path) -> None:
    """`trajcache serve --workers 2`: whichever worker answers /metrics counts all plans."""
    port = free_port()
    env = {
        **os.environ,
        "TRAJCACHE_DATABASE_URL": f"sqlite:///{tmp_path / 'served.db'}",
        "TRAJCACHE_WORKER_PRESTART": "false",
        "TRAJCACHE_LOG_LEVEL": "warning",
        MULTIPROC_ENV: str(tmp_path / "prometheus"),
    }
    command = [sys.executable, "-m", "trajcache.cli", "serve", "--port", str(port)]
    proc = subprocess.Popen([*command, "--workers", "2"], env=env, cwd=tmp_path)
    base = f"http://127.0.0.1:{port}"
    try:
        _wait_ready(base, proc)
        model = httpx.post(f"{base}/v1/robot-models", json={"urdf": TWO_JOINT_URDF}).json()
        robot = httpx.put(f"{base}/v1/robots/w-1", json={"model_id": model["model_id"]})
        assert robot.status_code == 201
        stored = httpx.post(
            f"{base}/v1/trajectories", json={"model_id": model["model_id"], "states": PATH}
        )
        assert stored.status_code == 201
        body = {"start": [0.0, 0.0], "goal": [1.0, 0.0], "options": {"fallback": False}}
        for _ in range(12):  # a new connection each: the workers share them out
            assert httpx.post(f"{base}/v1/robots/w-1/plan", json=body).json()["source"] == "cache"
        seen = set()
        for _ in range(8):
            merged = samples(httpx.get(f"{base}/metrics").text)
            seen.add(
                value(
                    merged,
                    "trajcache_plan_requests_total",
                    source="cache",
                    status="success",
                    requester="robot",
                )
            )
        assert seen == {12.0}
        # Both workers write their samples where every /metrics reads them.
        pids = {p.stem.split("_")[-1] for p in (tmp_path / "prometheus").glob("counter_*.db")}
        assert len(pids) >= 2  # (the supervisor process may have a file too)
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def free_port() -> int:
    """An unused loopback port."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _wait_ready(base: str, proc: subprocess.Popen[bytes]) -> None:
    def ready() -> bool:
        try:
            return httpx.get(f"{base}/readyz", timeout=1.0).status_code == 200
        except httpx.HTTPError:
            return False

    wait_until(lambda: proc.poll() is not None or ready(), timeout_s=90, interval_s=0.3)
    assert proc.poll() is None, "the service exited"
    assert ready(), "the service did not become ready"
