"""The dashboard in headless Chromium, over the real service seeded by real plan calls.

The service runs as `trajcache serve` on loopback with a SQLite file; two cleaning runs of the
reference robot in the restroom (the first fills the cache through the planner, the second reuses
it) go through `POST /v1/robots/{id}/plan`, then a small seed job plans some of the same calls.
The page must load that data, draw every chart, fill every table (the seed job in its own, not
among the robots) and log no error. A screenshot is saved to `artifacts/dashboard.png`.

Needs Debian's chromium (`/usr/bin/chromium`, driven by Playwright): skipped without it, failed
when TRAJCACHE_REQUIRE_SERVICES=1.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.conftest import REQUIRE_SERVICES
from tests.waiting import wait_until

CHROMIUM = Path("/usr/bin/chromium")
ARTIFACTS = Path(__file__).resolve().parents[2] / "artifacts"
CALLS_PER_RUN = 60
SEED_JOB_CALLS = 4
WAIT_MS = 60_000  # generous: the machine running the tests may be busy
CHARTS = ("chart-hit-rate", "chart-time-saved", "chart-calls", "chart-latency", "chart-joints")

pytestmark = pytest.mark.slow


def _require_browser() -> Any:
    """Playwright's sync API, or a skip (a failure in CI) when the browser is missing."""
    problem = None
    if not CHROMIUM.exists():
        problem = f"{CHROMIUM} is not installed (apt-get install chromium)"
    try:
        from playwright import sync_api
    except ImportError:
        problem = problem or "the playwright package is not installed"
    if problem:
        if REQUIRE_SERVICES:
            pytest.fail(f"{problem} and TRAJCACHE_REQUIRE_SERVICES=1")
        pytest.skip(problem)
    return sync_api


@dataclass
class Seeded:
    """The running service and what was sent to it."""

    base: str
    env: dict[str, str]
    requests: int = 0
    sources: dict[str, int] = field(default_factory=dict)
    robots: set[str] = field(default_factory=set)
    job: dict[str, Any] = field(default_factory=dict)  # the seed job, once it ended
    model_id: str = ""  # the robots' model, registered as "xarm7-mobile"


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _wait_ready(base: str, proc: subprocess.Popen[bytes]) -> None:
    def ready() -> bool:
        try:
            return httpx.get(f"{base}/readyz", timeout=1.0).status_code == 200
        except httpx.HTTPError:
            return False

    wait_until(lambda: proc.poll() is not None or ready(), timeout_s=120, interval_s=0.3)
    assert proc.poll() is None, "the service exited before it was ready"
    assert ready(), "the service did not become ready"


def _seed(client: httpx.Client, seeded: Seeded) -> None:
    """Register the reference robot; run a cleaning run on it, then another on a second robot."""
    from trajcache.geometry.scene.payload import scene_to_payload
    from trajcache.reference.cleaning import cleaning_run
    from trajcache.reference.robot import reference_urdf

    reply = client.post(
        "/v1/robot-models",
        json={"urdf": reference_urdf(), "base": "planar", "name": "xarm7-mobile"},
    )
    assert reply.status_code in (200, 201), reply.text
    model_id = reply.json()["model_id"]
    replayable: list[tuple[object, Any, dict[str, Any]]] = []  # (scene key, scene, body)
    for robot, seed in (("cleaner-1", 11), ("cleaner-2", 12)):
        assert client.put(f"/v1/robots/{robot}", json={"model_id": model_id}).status_code == 201
        run = cleaning_run(seed)
        scene_key: object = None
        for call in run.calls[:CALLS_PER_RUN]:
            key = (call.doors_deg, call.seats_deg)
            if key != scene_key:
                payload = scene_to_payload(run.scene_for(call))
                assert client.put(f"/v1/robots/{robot}/scene", json=payload).status_code == 200
                scene_key = key
            body = {"start": call.start.tolist(), "goal": call.goal.tolist()}
            reply = client.post(f"/v1/robots/{robot}/plan", json=body)
            assert reply.status_code == 200, reply.text
            source = reply.json()["source"] or "none"
            seeded.sources[source] = seeded.sources.get(source, 0) + 1
            seeded.requests += 1
            if robot == "cleaner-1" and source != "none":
                replayable.append((key, payload, body))
        seeded.robots.add(robot)
    # A plan refused (422: a goal of one value for a robot of ten): a refusal, not a failure.
    reply = client.post("/v1/robots/cleaner-2/plan", json={"start": body["start"], "goal": [0.0]})
    assert reply.status_code == 422, reply.text
    seeded.model_id = model_id
    _run_seed_job(client, seeded, model_id, replayable)


def _run_seed_job(
    client: httpx.Client,
    seeded: Seeded,
    model_id: str,
    replayable: list[tuple[object, Any, dict[str, Any]]],
) -> None:
    """A seed job of calls the first robot got a path for in its first scene; waits for its end."""
    first, scene, _ = replayable[0]
    queries = [body for key, _, body in replayable if key == first][:SEED_JOB_CALLS]
    assert len(queries) == SEED_JOB_CALLS, len(queries)
    spec = {"model_id": model_id, "name": "replay", "scenes": [scene], "queries": queries}
    reply = client.post("/v1/seed-jobs", json=spec)
    assert reply.status_code == 202, reply.text
    path = f"/v1/seed-jobs/{reply.json()['job_id']}"

    def ended() -> bool:
        seeded.job = client.get(path).json()
        return seeded.job["state"] not in ("queued", "running")

    assert wait_until(ended, timeout_s=120, interval_s=0.3), seeded.job
    assert seeded.job["state"] == "completed" and seeded.job["failed"] == 0, seeded.job


@contextmanager
def _service(tmp: Path) -> Iterator[tuple[str, dict[str, str]]]:
    """`trajcache serve` on a free loopback port with a SQLite file in `tmp`: (URL, env)."""
    port = _free_port()
    env = {
        **os.environ,
        "TRAJCACHE_DATABASE_URL": f"sqlite:///{tmp / 'dashboard.db'}",
        "TRAJCACHE_WORKER_PROCESSES": "1",
        "TRAJCACHE_LOG_LEVEL": "warning",
    }
    command = [sys.executable, "-m", "trajcache.cli", "serve", "--host", "127.0.0.1"]
    proc = subprocess.Popen([*command, "--port", str(port)], env=env, cwd=tmp)
    base = f"http://127.0.0.1:{port}"
    try:
        _wait_ready(base, proc)
        yield base, env
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()


@pytest.fixture(scope="module")
def seeded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Seeded]:
    """The service on loopback, after two cleaning runs of real plan calls."""
    _require_browser()
    with _service(tmp_path_factory.mktemp("dashboard")) as (base, env):
        state = Seeded(base=base, env=env)
        with httpx.Client(base_url=base, timeout=60) as client:
            _seed(client, state)
        yield state


@pytest.fixture
def page(seeded: Seeded) -> Iterator[tuple[Any, list[str]]]:
    """A fresh Chromium page, and the errors it logs (console errors and uncaught exceptions)."""
    sync_api = _require_browser()
    errors: list[str] = []
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=["--no-sandbox"]
        )
        try:
            tab = browser.new_page(viewport={"width": 1400, "height": 1000})
            tab.on(
                "console",
                lambda m: errors.append(f"{m.type}: {m.text}") if m.type == "error" else None,
            )
            tab.on("pageerror", lambda exc: errors.append(f"uncaught: {exc}"))
            yield tab, errors
        finally:
            browser.close()


def _rows(tab: Any, table: str) -> list[list[str]]:
    rows: list[list[str]] = tab.eval_on_selector_all(
        f"#{table} tbody tr",
        "rows => rows.map(r => Array.from(r.cells).map(c => c.textContent.trim()))",
    )
    return rows


def test_dashboard_shows_the_seeded_runs(page: tuple[Any, list[str]], seeded: Seeded) -> None:
    tab, errors = page
    assert seeded.sources.get("planner", 0) > 0 and seeded.sources.get("cache", 0) > 0, (
        seeded.sources
    )
    tab.goto(f"{seeded.base}/dashboard")  # redirected to /dashboard/
    tab.wait_for_function("document.body.dataset.window === '24h'", timeout=WAIT_MS)
    # a 24-hour window on a service that ran for a minute or less: charted over its last minute
    # in 5-second buckets, not in hours (one dot); tests/services/stats has the young service
    assert "buckets of 5 s" in tab.inner_text("#status")
    tab.select_option("#window", "5m")  # 5-second buckets: the runs span several
    tab.wait_for_function("document.body.dataset.window === '5m'", timeout=WAIT_MS)

    for chart in CHARTS:
        points = int(tab.get_attribute(f"#{chart}", "data-points") or 0)
        shapes = tab.eval_on_selector(f"#{chart}", "s => s.querySelectorAll('path, rect').length")
        assert points > 0 and shapes > 0, (chart, points, shapes)
    labels = tab.eval_on_selector_all("#kpis .kpi", "ks => ks.map(k => k.innerText)")
    kpis = {text.split("\n")[0].lower(): text.split("\n")[1] for text in labels}
    job = seeded.job
    assert kpis["requests"] == str(seeded.requests + job["total"])  # robots and the seed job
    hit_rate = 100 * (seeded.sources["cache"] + job["hits"]) / (seeded.requests + job["total"])
    assert kpis["hit rate"] == f"{hit_rate:.1f} %"
    assert kpis["time saved"] not in ("–", "0.00 ms")
    assert kpis["refusals"] == "1" and kpis["failures"] == "0"  # apart from failures
    [refusal] = _rows(tab, "refusals-table")
    assert refusal[1:3] == ["cleaner-2", "xarm7-mobile"] and refusal[3].startswith("422: goal")

    robots = _rows(tab, "robots-table")
    assert sorted(r[0] for r in robots) == sorted(seeded.robots)  # the seed job is not a robot
    assert sum(int(r[1].replace(",", "")) for r in robots) == seeded.requests
    total = job["total"]
    assert _rows(tab, "seed-jobs-table") == [
        [
            f"#{job['job_id']} replay",
            "completed",
            f"{total} / {total} (100.0 %)",
            str(total),
            f"{100 * job['hits'] / total:.1f} %",
            "0",
        ]
    ]
    top = _rows(tab, "top-table")
    assert top and all(r[0].startswith("#") for r in top)
    assert {r[1] for r in top} == {"xarm7-mobile"}  # models by name, the hash on hover
    hover = tab.eval_on_selector_all("#top-table td.model", "cs => cs.map(c => c.title)")
    assert set(hover) == {seeded.model_id}
    refused = {r[0]: r[5] for r in robots}  # each robot's refusals, in a column of their own
    assert refused == {"cleaner-1": "0", "cleaner-2": "1"}
    events = _rows(tab, "events-table")
    assert len(events) == 15
    goals = {(row[2] == "refused", row[3]) for row in events}  # every goal here is a state
    assert goals <= {(False, "joint"), (True, "–")} and (False, "joint") in goals
    asked = {row[1] for row in events}  # the seed job ran last: it is among the latest
    assert f"seed job #{job['job_id']}" in asked and asked <= {
        *seeded.robots,
        f"seed job #{job['job_id']}",
    }
    usage = _rows(tab, "usage-table")
    assert usage and usage[0][0] != "Not used yet"
    legend = tab.eval_on_selector_all(
        "#chart-joints .legend text", "ts => ts.map(t => t.textContent)"
    )
    assert "base_x" in legend and "joint7" in legend

    # The inspector plots any trajectory asked for: the one with the most key states.
    listed = httpx.get(f"{seeded.base}/v1/trajectories", params={"limit": 1000}).json()["items"]
    longest = max(listed, key=lambda t: t["n_states"])
    tab.fill("#inspect-id", str(longest["trajectory_id"]))
    tab.click("#inspect-form button[type=submit]")
    tab.wait_for_function(
        "document.getElementById('inspect-meta').textContent"
        f".startsWith('#{longest['trajectory_id']} ')"
    )
    points = int(tab.get_attribute("#chart-joints", "data-points") or 0)
    assert points == longest["n_states"] * longest["dof"]

    ARTIFACTS.mkdir(exist_ok=True)
    tab.screenshot(path=str(ARTIFACTS / "dashboard.png"), full_page=True)
    assert not errors, errors


def test_inspector_follows_a_clicked_trajectory_and_the_page_refreshes_itself(
    page: tuple[Any, list[str]], seeded: Seeded
) -> None:
    tab, errors = page
    tab.goto(f"{seeded.base}/dashboard/")
    tab.wait_for_function("document.body.dataset.state === 'ready'", timeout=WAIT_MS)
    links = tab.query_selector_all("#top-table a.traj")
    assert len(links) >= 2
    wanted = links[1].inner_text()
    links[1].click()
    tab.wait_for_function(
        f"document.getElementById('inspect-meta').textContent.startsWith('{wanted} ')"
    )
    assert int(tab.get_attribute("#chart-joints", "data-points") or 0) > 0
    tab.select_option("#latency-metric", "plan_ms")
    assert int(tab.get_attribute("#chart-latency", "data-points") or 0) > 0
    before = int(tab.get_attribute("body", "data-refreshes") or 0)
    tab.select_option("#refresh-every", "5")
    tab.wait_for_function(f"Number(document.body.dataset.refreshes) > {before}", timeout=WAIT_MS)
    assert tab.input_value("#inspect-id") == wanted.lstrip("#")  # kept across refreshes
    assert not errors, errors


def test_an_empty_service_shows_empty_charts_and_tables(
    page: tuple[Any, list[str]], tmp_path: Path
) -> None:
    tab, errors = page
    with _service(tmp_path) as (base, _env):
        tab.goto(f"{base}/dashboard/")
        tab.wait_for_function("document.body.dataset.state === 'ready'", timeout=WAIT_MS)
        for chart in CHARTS:
            assert tab.get_attribute(f"#{chart}", "data-points") == "0", chart
            assert tab.eval_on_selector(f"#{chart}", "s => s.textContent") != ""
        assert _rows(tab, "robots-table") == [["No robot planned in this window"]]
        assert _rows(tab, "seed-jobs-table") == [["No seed jobs"]]
        assert _rows(tab, "top-table") == [["The cache is empty"]]
        assert _rows(tab, "events-table") == [["No plan events yet"]]
    assert not errors, errors


def test_the_page_asks_for_an_admin_key_once_keys_exist(
    page: tuple[Any, list[str]], seeded: Seeded
) -> None:
    created = subprocess.run(
        [
            sys.executable,
            "-m",
            "trajcache.cli",
            "keys",
            "create",
            "--name",
            "ops",
            "--role",
            "admin",
        ],
        env=seeded.env,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    secret = created.stdout.strip().splitlines()[-1]
    tab, _errors = page  # the refused requests are logged by the browser; that is expected here
    assert wait_until(  # keys are cached briefly
        lambda: httpx.get(f"{seeded.base}/v1/stats").status_code == 401,
        timeout_s=30,
        interval_s=0.5,
    ), "the service did not start requiring keys"
    tab.goto(f"{seeded.base}/dashboard/")
    tab.wait_for_function("document.body.dataset.state === 'auth'", timeout=WAIT_MS)
    assert tab.is_visible("#key-panel")
    tab.fill("#key-input", secret)
    tab.click("#key-form button[type=submit]")
    tab.wait_for_function("document.body.dataset.state === 'ready'", timeout=WAIT_MS)
    assert len(_rows(tab, "robots-table")) == len(seeded.robots)
