"""PlannerPool on the Celery backend, against a real worker process and the local Redis."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import redis
from typer.testing import CliRunner

from tests.conftest import REDIS_URL, require_service
from tests.jobs.test_pool import (
    assert_one_numeric_thread,
    make_problem,
    runs,
    submit_all,
    two_link_problem,
)
from tests.proxy import TcpProxy
from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.db import migrate
from trajcache.db import models as tables
from trajcache.db.session import make_engine, make_sessionmaker
from trajcache.jobs.celery_app import TASK_FN_ENV, CeleryBackend, make_celery
from trajcache.jobs.pool import PlannerPool
from trajcache.planning.problem import ModelSource, PlannerStatus, PlanningProblem, PlanResult

ROOT = Path(__file__).resolve().parents[2]
SCRIPTED = "tests.jobs.test_pool:scripted_task"
pytestmark = pytest.mark.redis


class Worker:
    """A Celery worker in its own process, consuming a queue of its own, reading models and
    scenes from `database_url`; with Celery's default settings otherwise, as the user the tests
    run as (root in CI containers: nothing allows it more than any other user)."""

    def __init__(
        self,
        command: list[str],
        queue: str,
        log: Path,
        redis_url: str,
        task_fn: str | None,
        *,
        database_url: str,
    ) -> None:
        self.queue = queue
        self.log = log
        self.redis_url = redis_url
        env = {
            **os.environ,
            "TRAJCACHE_DATABASE_URL": database_url,
            "TRAJCACHE_CELERY_BROKER_URL": redis_url,
            "TRAJCACHE_CELERY_RESULT_BACKEND": redis_url,
            "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
        }
        for name in (TASK_FN_ENV, "C_FORCE_ROOT"):
            env.pop(name, None)
        if task_fn is not None:
            env[TASK_FN_ENV] = task_fn
        with log.open("wb") as out:
            self.process = subprocess.Popen(
                command, cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT
            )

    def stop(self) -> None:
        self.process.terminate()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        client = redis.Redis.from_url(self.redis_url)
        keys = list(client.scan_iter(f"*{self.queue}*"))  # the queue and its kombu bindings
        if keys:
            client.delete(*keys)
        client.close()

    def wait_ready(self, timeout_s: float = 120.0) -> None:
        """Wait until Celery logs that the worker consumes its queue (slow on a loaded machine)."""
        started = wait_until(
            lambda: self.process.poll() is not None or " ready." in self.log_tail(),
            timeout_s=timeout_s,
        )
        assert started and self.process.poll() is None, self.log_tail()

    def log_tail(self) -> str:
        return self.log.read_text(errors="replace")[-3000:]


def celery_pool(redis_url: str, queue: str) -> PlannerPool:
    settings = Settings(
        worker_backend="celery", celery_broker_url=redis_url, celery_result_backend=redis_url
    )
    return PlannerPool(CeleryBackend(settings, queue=queue), negative_cache_ttl_s=0.0)


def wait_for_worker(pool: PlannerPool, worker: Worker, ping: PlanningProblem) -> None:
    """Submit until the worker answers (it discards the expired attempts)."""
    answered = wait_until(
        lambda: worker.process.poll() is not None or pool.submit(ping).solved, timeout_s=30.0
    )
    assert worker.process.poll() is None, f"worker exited:\n{worker.log_tail()}"
    assert answered, f"the Celery worker did not answer within 30 s:\n{worker.log_tail()}"


def store_models(database_url: str, *sources: ModelSource) -> str:
    """Migrate `database_url` and store `sources` under their ids, where a worker reads them."""
    migrate.upgrade(database_url)
    engine = make_engine(database_url)
    try:
        with make_sessionmaker(engine)() as session:
            for source in sources:
                row = tables.RobotModel(
                    id=source.model_id,
                    name=source.model_id,
                    base=source.base,
                    joint_names=list(source.joint_names),
                    urdf=source.urdf,
                    config={},
                )
                session.merge(row)
            session.commit()
    finally:
        engine.dispose()
    return database_url


def start_worker(
    command: list[str],
    queue: str,
    tmp_path: Path,
    *,
    task_fn: str | None = SCRIPTED,
    database_url: str | None = None,
) -> tuple[Worker, PlannerPool]:
    """Start a worker on `database_url` (default: a SQLite file of its own) and wait until it
    plans; the real planner when `task_fn` is None."""
    ping = make_problem(tmp_path, scene="ping", budget_s=1.0)
    if task_fn is None:
        ping = replace(two_link_problem((2.0, 1.0)), budget_s=1.0)
    database_url = store_models(database_url or f"sqlite:///{tmp_path / 'models.db'}", ping.model)
    worker = Worker(
        command, queue, tmp_path / "worker.log", REDIS_URL, task_fn, database_url=database_url
    )
    pool = celery_pool(REDIS_URL, queue)
    try:
        wait_for_worker(pool, worker, ping)
    except BaseException:
        pool.close()
        worker.stop()
        raise
    return worker, pool


@pytest.fixture(scope="module")
def celery_worker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Worker, PlannerPool]]:
    """A prefork worker started with `celery -A trajcache.jobs.celery_app worker`."""
    require_service("Redis", "127.0.0.1", 6379)
    queue = f"plan-test-{uuid.uuid4().hex[:8]}"
    command = [
        sys.executable,
        "-m",
        "celery",
        "-A",
        "trajcache.jobs.celery_app",
        "worker",
        "--pool=prefork",
        "-c",
        "2",
        "-Q",
        queue,
        "-n",
        f"{queue}@%h",
        "--loglevel=INFO",
        "--without-gossip",
        "--without-mingle",
        "--without-heartbeat",
    ]
    worker, pool = start_worker(command, queue, tmp_path_factory.mktemp("celery"))
    yield worker, pool
    pool.close()
    worker.stop()


def parent_pid(pid: int) -> int:
    return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])


def test_plans_in_the_worker_process(
    celery_worker: tuple[Worker, PlannerPool], redis_url: str, tmp_path: Path
) -> None:
    worker, pool = celery_worker
    result = pool.submit(make_problem(tmp_path, start=(0.5, -0.5)))
    assert result.status is PlannerStatus.SOLVED, result.message
    assert result.path is not None and result.path.tolist() == [[0.5, -0.5], [1.0, 1.0]]
    pid = int(result.stats["pid"])
    assert pid != os.getpid()
    assert parent_pid(pid) == worker.process.pid  # a prefork child of the worker we started
    assert runs(tmp_path) == 1


def test_worker_processes_run_one_numeric_thread(
    celery_worker: tuple[Worker, PlannerPool], redis_url: str, tmp_path: Path
) -> None:
    _, pool = celery_worker
    assert_one_numeric_thread(pool.submit(make_problem(tmp_path, scene="threads", threads=True)))


def test_concurrent_requests_and_coalescing(
    celery_worker: tuple[Worker, PlannerPool], redis_url: str, tmp_path: Path
) -> None:
    _, pool = celery_worker
    distinct = [make_problem(tmp_path, scene=f"s{i}", sleep=0.2) for i in range(4)]
    same = [make_problem(tmp_path, scene="same", sleep=1.0)] * 4
    results = submit_all(pool, distinct + same)
    assert all(r.solved for r in results), [r.message for r in results]
    assert [runs(tmp_path, f"s{i}") for i in range(4)] == [1] * 4
    assert runs(tmp_path, "same") == 1
    assert all(r is results[4] for r in results[4:])


def test_task_exception_is_an_error_result(
    celery_worker: tuple[Worker, PlannerPool], redis_url: str, tmp_path: Path
) -> None:
    _, pool = celery_worker
    result = pool.submit(make_problem(tmp_path, explode=True))
    assert result.status is PlannerStatus.ERROR
    assert "failed in the worker" in result.message and "planner exploded" in result.detail


def test_crashed_worker_process_is_an_error_result(
    celery_worker: tuple[Worker, PlannerPool], redis_url: str, tmp_path: Path
) -> None:
    _, pool = celery_worker
    result = pool.submit(make_problem(tmp_path, budget_s=10.0, exit=True))
    # An error at the crash, not a timeout at the end of the 10 s budget.
    assert result.status is PlannerStatus.ERROR and "WorkerLostError" in result.detail
    assert pool.submit(make_problem(tmp_path, scene="after")).solved


def test_budget_is_enforced(
    celery_worker: tuple[Worker, PlannerPool], redis_url: str, tmp_path: Path
) -> None:
    _, pool = celery_worker
    done = tmp_path / "done"
    result = pool.submit(make_problem(tmp_path, budget_s=0.3, sleep=2.0, done_file=str(done)))
    # Given up after the budget and the 1 s overhead, not when the 2 s task finished.
    assert result.status is PlannerStatus.TIMEOUT, result.message
    assert "budget of 0.3 s (no answer after 1.3 s)" in result.message
    assert not done.exists()
    assert wait_until(done.exists)  # the worker is free again for the next test


def test_workers_take_json_only() -> None:
    conf = make_celery(Settings()).conf
    assert (conf.accept_content, conf.result_accept_content) == (["json"], ["json"])
    assert (conf.task_serializer, conf.result_serializer) == ("json", "json")


def test_cli_worker_runs_the_real_planner(redis_url: str, tmp_path: Path) -> None:
    """`trajcache worker` with the default settings plans, also as root (as the tests run in CI
    containers): Celery refuses only workers that accept pickle as root."""
    queue = f"plan-cli-{uuid.uuid4().hex[:8]}"
    code = "import typer; from trajcache.cli.worker import worker; typer.run(worker)"
    command = [sys.executable, "-c", code, "--concurrency", "1", "--queues", queue]
    worker, pool = start_worker(command, queue, tmp_path, task_fn=None)
    try:
        result = pool.submit(replace(two_link_problem((-1.0, 2.0)), seed=3))
        assert result.solved, result.message
        assert result.path is not None
        assert np.allclose(result.path[[0, -1]], [[0.0, 0.0], [-1.0, 2.0]])
        assert "run_ms" in result.stats  # run_planning's own statistics
        blocked = pool.submit(two_link_problem((1.5708, 0.0)))
        assert blocked.status is PlannerStatus.INVALID_GOAL, blocked.message
        # The worker plans the model its database holds under the task's model id.
        unknown = replace(two_link_problem((-1.0, 2.0)), model=make_problem(tmp_path).model)
        missing = pool.submit(unknown)
        assert missing.status is PlannerStatus.ERROR
        assert "robot model 'model-1' not found in the worker's database" in missing.message
    finally:
        pool.close()
        worker.stop()


def test_worker_cli_arguments(monkeypatch: pytest.MonkeyPatch) -> None:
    import typer

    from trajcache.cli import worker as worker_cli
    from trajcache.jobs import celery_app

    seen: list[list[str]] = []
    monkeypatch.setattr(celery_app.celery_app, "worker_main", seen.append)
    app = typer.Typer()
    app.command()(worker_cli.worker)
    result = CliRunner().invoke(app, ["--concurrency", "3", "--queues", "plan,other"])
    assert result.exit_code == 0, result.output
    assert seen == [["worker", "--concurrency=3", "--loglevel=info", "--queues=plan,other"]]
    monkeypatch.setenv("TRAJCACHE_WORKER_PROCESSES", "5")
    from trajcache.core.config import get_settings

    get_settings.cache_clear()
    try:
        assert CliRunner().invoke(app, []).exit_code == 0
    finally:
        get_settings.cache_clear()
    assert seen[-1][1] == "--concurrency=5"


# --- an unreachable broker ---


def test_unreachable_broker_is_an_error_result_quickly(tmp_path: Path) -> None:
    pool = celery_pool("redis://127.0.0.1:1/0", "plan")
    try:
        for _ in range(2):
            problem = make_problem(tmp_path, budget_s=10.0)
            began = time.monotonic()
            result = pool.submit(problem)
            # Fail fast is the promise: the refused connection is not retried for the budget.
            assert time.monotonic() - began < problem.budget_s
            assert result.status is PlannerStatus.ERROR
            assert result.message == "worker backend unavailable" and result.detail
        assert pool.stats().negative_hits == 0
    finally:
        pool.close()


def test_recovers_when_redis_comes_back(
    celery_worker: tuple[Worker, PlannerPool], redis_url: str, tmp_path: Path
) -> None:
    worker, _ = celery_worker
    proxy = TcpProxy(("127.0.0.1", 6379))
    proxied = REDIS_URL.replace("127.0.0.1:6379", f"127.0.0.1:{proxy.port}")
    assert proxied != REDIS_URL
    pool = celery_pool(proxied, worker.queue)  # created while "Redis" is down

    def plan(scene: str) -> PlanResult:
        problem = make_problem(tmp_path, scene=scene, budget_s=3.0)
        began = time.monotonic()
        result = pool.submit(problem)
        # submit's promise: it never outlives the budget and the overhead, Redis down or not.
        assert time.monotonic() - began < problem.budget_s + pool.overhead_s
        return result

    try:
        for cycle in range(2):
            down = plan(f"down-{cycle}")
            assert down.status is PlannerStatus.ERROR and "unavailable" in down.message
            proxy.start()
            up = plan(f"up-{cycle}")
            assert up.solved, up.message
            proxy.stop()
        assert pool.stats().negative_hits == 0
    finally:
        pool.close()
        proxy.stop()
