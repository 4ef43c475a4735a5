"""`trajcache seed FILE` against a live service (uvicorn in a thread, real HTTP)."""

from __future__ import annotations

import json
import re
import socket
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
import uvicorn
import yaml
from typer.testing import CliRunner

from tests.client.conftest import LiveServer, make_app
from tests.robots import TWO_JOINT_URDF
from tests.waiting import wait_until
from trajcache.cli import app
from trajcache.core.config import Settings
from trajcache.main import create_app
from trajcache.reference.robot import reference_urdf

SCENE = {
    "objects": [{"id": "far", "type": "sphere", "size": [0.05], "pose": {"position": [2, 2, 2]}}]
}


class LiveService:
    """The app served by uvicorn on a free local port."""

    def __init__(self, settings: Settings) -> None:
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            self.port = probe.getsockname()[1]
        config = uvicorn.Config(
            create_app(settings), host="127.0.0.1", port=self.port, log_level="warning"
        )
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, daemon=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def __enter__(self) -> LiveService:
        self.thread.start()
        assert wait_until(lambda: self.server.started, timeout_s=30), "the service did not start"
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=30)


@pytest.fixture
def service(tmp_path: Path) -> Iterator[tuple[LiveService, str]]:
    settings = Settings(
        database_url=f"sqlite:///{tmp_path / 'live.db'}",
        worker_backend="none",
        seed_heartbeat_s=0.1,
        seed_poll_interval_s=0.1,
    )
    with LiveService(settings) as live:
        model = httpx.post(f"{live.url}/v1/robot-models", json={"urdf": TWO_JOINT_URDF}).json()
        stored = httpx.post(
            f"{live.url}/v1/trajectories",
            json={"model_id": model["model_id"], "states": [[0, 0], [0.5, 0.5]]},
        )
        assert stored.status_code == 201, stored.text
        yield live, model["model_id"]


def job_file(tmp_path: Path, goals: list[list[float]], suffix: str = ".json", **extra: Any) -> Path:
    body = {"scenes": [SCENE], "queries": [{"start": [0, 0], "goal": g} for g in goals], **extra}
    path = tmp_path / f"job{suffix}"
    path.write_text(yaml.safe_dump(body) if suffix == ".yaml" else json.dumps(body))
    return path


def test_seed_follows_the_job_to_the_end(service: tuple[LiveService, str], tmp_path: Path) -> None:
    live, model_id = service
    path = job_file(tmp_path, [[0.5, 0.5], [0.51, 0.49], [-1.0, 1.0]], suffix=".yaml")
    result = CliRunner().invoke(
        app, ["seed", str(path), "--url", live.url, "--model", model_id, "--poll-s", "0.05"]
    )
    assert result.exit_code == 0, result.output
    assert "queued seed job 1: 3 requests" in result.output
    assert "cache hits" in result.output and "2 (66.7%)" in result.output
    assert "failed #2" in result.output and "miss" in result.output
    job = httpx.get(f"{live.url}/v1/seed-jobs/1").json()
    assert (job["state"], job["hits"], job["failed"]) == ("completed", 2, 1)


def test_seed_without_waiting_prints_the_job_id(
    service: tuple[LiveService, str], tmp_path: Path
) -> None:
    live, model_id = service
    path = job_file(tmp_path, [[0.5, 0.5]], model_id=model_id)
    result = CliRunner().invoke(
        app, ["seed", str(path), "--no-wait"], env={"TRAJCACHE_URL": live.url}
    )
    assert result.exit_code == 0, result.output
    assert result.stdout.strip().splitlines()[-1] == "1"


def test_a_refused_job_exits_2_with_the_reason(
    service: tuple[LiveService, str], tmp_path: Path
) -> None:
    live, model_id = service
    path = job_file(tmp_path, [[0.5, 9.0]])
    result = CliRunner().invoke(app, ["seed", str(path), "--url", live.url, "--model", model_id])
    assert result.exit_code == 2
    assert "422" in result.output and "queries[0].goal" in result.output


def test_unreachable_service_and_bad_files(tmp_path: Path) -> None:
    path = job_file(tmp_path, [[0.5, 0.5]], model_id="m")
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    result = CliRunner().invoke(app, ["seed", str(path), "--url", f"http://127.0.0.1:{port}"])
    assert result.exit_code == 1
    assert "cannot reach the service" in result.output
    bad = tmp_path / "bad.json"
    bad.write_text("[1, 2]")
    result = CliRunner().invoke(app, ["seed", str(bad)])
    assert result.exit_code == 2 and "one object" in result.output
    result = CliRunner().invoke(app, ["seed", str(tmp_path / "missing.json")])
    assert result.exit_code == 2 and "cannot read" in result.output


def test_a_job_may_name_its_model(service: tuple[LiveService, str], tmp_path: Path) -> None:
    live, model_id = service
    path = job_file(tmp_path, [[0.5, 0.5]], suffix=".yaml", model="two_joint")
    result = CliRunner().invoke(app, ["seed", str(path), "--url", live.url, "--poll-s", "0.05"])
    assert result.exit_code == 0, result.output
    assert httpx.get(f"{live.url}/v1/seed-jobs/1").json()["model_id"] == model_id
    for extra, message in [
        ({"model": "nobody"}, "no model named 'nobody'"),
        ({"model": "two_joint", "model_id": model_id}, "not both"),
    ]:
        path = job_file(tmp_path, [[0.5, 0.5]], **extra)
        result = CliRunner().invoke(app, ["seed", str(path), "--url", live.url])
        assert result.exit_code == 2 and message in " ".join(result.output.split())
    assert len(httpx.get(f"{live.url}/v1/seed-jobs").json()["items"]) == 1


EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "sweep.yaml"


@pytest.mark.slow
def test_the_shipped_example_runs_as_it_is(tmp_path: Path) -> None:
    """`trajcache seed examples/sweep.yaml` against a service that knows nothing yet: the
    command registers the reference robot, and every request of the sweep succeeds."""
    app_ = make_app(
        f"sqlite:///{tmp_path / 'seed.db'}",
        worker_processes=1,
        seed_heartbeat_s=0.1,
        seed_poll_interval_s=0.1,
    )
    with LiveServer(app_) as server:
        result = CliRunner().invoke(
            app, ["seed", str(EXAMPLE), "--url", server.url, "--poll-s", "0.1"]
        )
        assert result.exit_code == 0, result.output
        job = httpx.get(f"{server.url}/v1/seed-jobs/1").json()
        reference = httpx.post(
            f"{server.url}/v1/robot-models", json={"urdf": reference_urdf(), "base": "planar"}
        ).json()
        stored = httpx.get(f"{server.url}/v1/trajectories", params={"source": "sim"}).json()
    assert (job["state"], job["done"], job["total"], job["failed"]) == ("completed", 9, 9, 0)
    assert job["model_id"] == reference["model_id"] and not reference["created"]
    # what the planner found is stored as sim; two identical paths are one trajectory
    assert 0 < stored["total"] <= job["planned"]


def test_a_locked_service_names_the_key_options(tmp_path: Path) -> None:
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'locked.db'}", auth_mode="on")
    with LiveService(settings) as live:
        named = job_file(tmp_path, [[0.5, 0.5]], model="reference")
        result = CliRunner().invoke(app, ["seed", str(named), "--url", live.url])
        output = " ".join(result.output.split())
        assert result.exit_code == 2 and "model 'reference': 401" in output
        assert "--api-key or TRAJCACHE_API_KEY" in output
        given = job_file(tmp_path, [[0.5, 0.5]], model_id="m")
        result = CliRunner().invoke(app, ["seed", str(given), "--url", live.url, "--api-key", "x"])
        output = " ".join(result.output.split())
        assert result.exit_code == 1 and "POST /v1/seed-jobs: 401" in output
        assert "--api-key or TRAJCACHE_API_KEY" in output


def _rows(job: dict[str, Any]) -> str:
    from rich.console import Console

    from trajcache.cli.seed import summary
    from trajcache_client import SeedJob

    console = Console(width=200, record=True)
    console.print(summary(SeedJob.model_validate(job)))
    return console.export_text()


def test_the_summary_counts_stored_and_already_stored_paths_apart() -> None:
    from trajcache.api.schemas.seed_jobs import JOB_OUT

    finished = {**JOB_OUT, "state": "completed", "done": 3, "total": 3, "hits": 0, "failed": 0}
    text = _rows({**finished, "planned": 3, "stored": 2, "errors": []})
    assert re.search(r"planned and stored \(as sim\)\s+│\s+2", text), text
    assert re.search(r"planned, already stored\s+│\s+1", text), text
    assert "planned (stored as sim)" not in text
    older = _rows({**finished, "planned": 3, "stored": None, "errors": []})
    assert re.search(r"planned\s+│\s+3", older) and "already stored" not in older
