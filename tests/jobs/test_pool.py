"""PlannerPool on the local process pool: budget, crashes, coalescing, negative cache."""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.robots import BOXED_TWO_LINK_URDF, OPAQUE_URDF
from tests.waiting import NEVER_BINDS_S, FakeClock, wait_until
from trajcache.core.config import Settings
from trajcache.jobs.local import LocalBackend
from trajcache.jobs.pool import PlannerPool, coalescing_key, make_pool
from trajcache.jobs.threads import ONE_THREAD_ENV, thread_counts
from trajcache.planning.problem import (
    ModelSource,
    PlannerStatus,
    PlanningProblem,
    PlanResult,
    SceneSource,
)

# --- stand-in task functions (top level, so they pickle by reference into the workers) ---


def scripted_task(problem: PlanningProblem) -> PlanResult:
    """Do what the scene payload says: log the run, report the pid (and the numeric threads),
    sleep, crash, fail, write a file once done."""
    script: dict[str, Any] = problem.scene.payload
    with open(script["log"], "a") as log:
        log.write(f"{os.getpid()}\n")
    if "pid_file" in script:
        Path(script["pid_file"]).write_text(str(os.getpid()))
    time.sleep(script.get("sleep", 0.0))  # a planner that takes this long: what is under test
    if "done_file" in script:
        Path(script["done_file"]).write_text(str(os.getpid()))
    if script.get("exit"):
        os._exit(1)
    if script.get("explode"):
        raise RuntimeError("planner exploded")
    status = PlannerStatus(script.get("status", "solved"))
    path = np.array([problem.start, problem.goal]) if status is PlannerStatus.SOLVED else None
    stats = {"pid": float(os.getpid())}
    if script.get("files"):  # what the task carried of the model's files, and what it can read
        model = problem.model
        stats["carried"] = float(sum(map(len, model.files.values())))
        stats["readable"] = float(sum(map(len, model.mesh_files().values())))
    if script.get("threads"):
        importlib.import_module("numba")  # as the planner's geometry kernels do
        stats.update({name: float(n) for name, n in thread_counts().items()})
        stats.update({name: float(os.environ.get(name, "0")) for name in ONE_THREAD_ENV})
    return PlanResult(
        status, path, message=f"scripted {status.value}", stats=stats, seed=problem.seed
    )


def assert_one_numeric_thread(result: PlanResult) -> None:
    """The worker that ran a `threads` script had every numeric thread pool at one thread."""
    assert result.status is PlannerStatus.SOLVED, result.message
    pools = [name for name in result.stats if name.startswith("openblas")]
    assert pools, "numpy's OpenBLAS was not found in the worker"
    expected = [*pools, "numba", *ONE_THREAD_ENV]
    assert {name: result.stats.get(name) for name in expected} == dict.fromkeys(expected, 1.0)


def make_problem(
    tmp_path: Path,
    *,
    start: tuple[float, ...] = (0.0, 0.0),
    goal: tuple[float, ...] = (1.0, 1.0),
    budget_s: float = 3.0,
    scene: str = "scene-a",
    **script: Any,
) -> PlanningProblem:
    model = ModelSource("model-1", OPAQUE_URDF, "fixed", ("j1", "j2"))
    payload = {"log": str(tmp_path / f"{scene}.log"), **script}
    return PlanningProblem(model, SceneSource(scene, payload), start, goal, budget_s=budget_s)


WALL = {
    "objects": [
        {
            "id": "wall",
            "type": "box",
            "size": [0.1, 0.1, 0.5],
            "pose": {"position": [0.0, 0.45, 0.0]},
        }
    ]
}


def test_a_model_s_mesh_files_wait_in_the_pool_s_spool_not_in_every_task(
    tmp_path: Path,
) -> None:
    mesh = bytes(range(256)) * 2_000
    model = ModelSource("meshy", OPAQUE_URDF, "fixed", ("j1", "j2"), files={"m.stl": mesh})
    problem = replace(make_problem(tmp_path, files=True), model=model)
    backend = LocalBackend(scripted_task, processes=1)
    try:
        first = backend.run(problem, timeout_s=NEVER_BINDS_S)
        second = backend.run(replace(problem, seed=2), timeout_s=NEVER_BINDS_S)
        spooled = backend._spool.source(model).files_at
    finally:
        backend.close()
    for result in (first, second):
        assert result.status is PlannerStatus.SOLVED, result.message
        assert result.stats["carried"] == 0.0 and result.stats["readable"] == len(mesh)
    assert spooled is not None and not Path(spooled).exists()  # gone with the pool
    assert model.mesh_files() == {"m.stl": mesh}  # the caller's source is left as it was


def test_the_caller_s_work_runs_while_its_task_plans_once_the_task_is_away(
    tmp_path: Path,
) -> None:
    done: list[tuple[int, bool]] = []  # (runs the worker had logged, whether it was done)
    problem = make_problem(tmp_path, sleep=0.3, done_file=str(tmp_path / "done"))

    def meanwhile() -> None:
        wait_until(lambda: runs(tmp_path) == 1)  # the task reached its worker and started
        done.append((runs(tmp_path), (tmp_path / "done").exists()))

    backend = LocalBackend(scripted_task, processes=1)
    try:
        result = backend.run(problem, timeout_s=NEVER_BINDS_S, meanwhile=meanwhile)
        failing = backend.run(problem, timeout_s=NEVER_BINDS_S, meanwhile=lambda: 1 / 0)
    finally:
        backend.close()
    assert result.status is PlannerStatus.SOLVED and done == [(1, False)]
    assert failing.status is PlannerStatus.SOLVED  # its error is logged, not the answer's


def two_link_problem(goal: tuple[float, float]) -> PlanningProblem:
    """A real problem for `run_planning`: a planar two-link arm next to a wall."""
    model = ModelSource("two-link", BOXED_TWO_LINK_URDF, "fixed", ("shoulder", "elbow"))
    scene = SceneSource("wall", WALL)
    return PlanningProblem(model, scene, (0.0, 0.0), goal, budget_s=NEVER_BINDS_S)


def runs(tmp_path: Path, scene: str = "scene-a") -> int:
    log = tmp_path / f"{scene}.log"
    return len(log.read_text().splitlines()) if log.exists() else 0


def make_local_pool(
    processes: int = 2,
    ttl: float = 30.0,
    grace: float = 5.0,
    clock: Callable[[], float] = time.monotonic,
) -> PlannerPool:
    backend = LocalBackend(scripted_task, processes=processes, overrun_grace_s=grace)
    return PlannerPool(backend, negative_cache_ttl_s=ttl, overhead_s=1.0, clock=clock)


@pytest.fixture
def pool() -> Iterator[PlannerPool]:
    with make_local_pool() as planner_pool:
        yield planner_pool


def submit_all(pool: PlannerPool, problems: list[PlanningProblem]) -> list[PlanResult]:
    """Submit from one thread per problem, all released at once."""
    results: list[PlanResult | None] = [None] * len(problems)
    barrier = threading.Barrier(len(problems))

    def one(i: int) -> None:
        barrier.wait()
        results[i] = pool.submit(problems[i])

    threads = [threading.Thread(target=one, args=(i,)) for i in range(len(problems))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=30)
    assert all(r is not None for r in results), "a submission hung"
    return [r for r in results if r is not None]


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = Path(f"/proc/{pid}/stat")  # a killed child may linger as a zombie until reaped
    return not (stat.exists() and stat.read_text().split(") ")[1].startswith("Z"))


# --- the worker process ---


def test_plans_in_another_process(pool: PlannerPool, tmp_path: Path) -> None:
    result = pool.submit(make_problem(tmp_path))
    assert result.status is PlannerStatus.SOLVED, result.message
    assert result.path is not None and result.path.tolist() == [[0.0, 0.0], [1.0, 1.0]]
    assert result.stats["pid"] != os.getpid()
    stats = pool.stats()
    assert (stats.submitted, stats.completed, stats.solved, stats.queue_depth) == (1, 1, 1, 0)


def test_workers_run_one_numeric_thread(pool: PlannerPool, tmp_path: Path) -> None:
    assert_one_numeric_thread(pool.submit(make_problem(tmp_path, threads=True)))


def test_task_exception_is_an_error_result(pool: PlannerPool, tmp_path: Path) -> None:
    result = pool.submit(make_problem(tmp_path, explode=True))
    assert result.status is PlannerStatus.ERROR
    assert "planning task raised" in result.message and "planner exploded" in result.detail
    assert pool.submit(make_problem(tmp_path, scene="ok")).solved


# --- the budget ---


def test_budget_is_enforced_and_an_overrunning_worker_is_recycled(tmp_path: Path) -> None:
    pid_file = tmp_path / "pid"
    with make_local_pool(grace=0.5) as pool:
        assert isinstance(pool.backend, LocalBackend) and pool.backend.wait_ready(60.0)
        result = pool.submit(make_problem(tmp_path, budget_s=0.5, sleep=5.0, pid_file=pid_file))
        # Given up after the budget and the 1 s overhead, not when the 5 s task finished.
        assert result.status is PlannerStatus.TIMEOUT, result.message
        assert "budget of 0.5 s (no answer after 1.5 s)" in result.message
        # written as the task began (late on a loaded machine)
        assert wait_until(lambda: pid_file.exists() and pid_file.read_text() != "")
        stuck = int(pid_file.read_text())
        assert wait_until(lambda: pool.stats().recycles == 1)
        assert wait_until(lambda: not pid_alive(stuck)), "stuck worker not killed"
        assert pool.submit(make_problem(tmp_path, scene="after")).solved
        assert pool.stats().crashes == 0


def test_waiting_for_a_free_worker_is_bounded_too(tmp_path: Path) -> None:
    with make_local_pool(processes=1) as pool:
        busy = threading.Thread(
            target=pool.submit, args=(make_problem(tmp_path, scene="busy", sleep=2.5),)
        )
        busy.start()
        assert wait_until(lambda: runs(tmp_path, "busy") == 1)  # the only worker is taken
        result = pool.submit(make_problem(tmp_path, scene="queued", budget_s=0.3))
        # Given up after the budget and the 1 s overhead, not when the worker became free.
        assert result.status is PlannerStatus.ERROR, result.message
        assert "no planning worker became free within 1.3 s" in result.message
        busy.join()
        assert runs(tmp_path, "queued") == 0  # cancelled before it started


# --- crashes ---


def test_crashed_worker_gives_an_error_and_the_pool_recovers(
    pool: PlannerPool, tmp_path: Path
) -> None:
    result = pool.submit(make_problem(tmp_path, exit=True))
    assert result.status is PlannerStatus.ERROR
    assert "planning worker crashed" in result.message
    later = [pool.submit(make_problem(tmp_path, scene=f"later-{i}")) for i in range(3)]
    assert all(r.solved for r in later), [r.message for r in later]
    stats = pool.stats()
    assert (stats.crashes, stats.recycles, stats.queue_depth) == (1, 1, 0)


def test_an_interrupt_sent_to_the_workers_is_left_to_the_service(tmp_path: Path) -> None:
    # Ctrl-C in a terminal signals the whole process group, the planning workers included
    with make_local_pool(processes=1) as pool:
        pid = int(pool.submit(make_problem(tmp_path)).stats["pid"])
        os.kill(pid, signal.SIGINT)
        # The signal reaches the worker before it takes another task: the one worker that
        # plans the next ones is the one interrupted, still there.
        after = [pool.submit(make_problem(tmp_path, scene=f"after-{i}")) for i in range(4)]
        assert all(r.solved for r in after), [r.message for r in after]
        assert [int(r.stats["pid"]) for r in after] == [pid] * 4
        assert pid_alive(pid)
        assert pool.stats().crashes == 0


def test_worker_killed_mid_request(pool: PlannerPool, tmp_path: Path) -> None:
    pid_file = tmp_path / "pid"
    problem = make_problem(tmp_path, budget_s=20.0, sleep=20.0, pid_file=pid_file)
    killed: list[int] = []

    def kill_the_worker() -> None:
        assert wait_until(lambda: pid_file.exists() and pid_file.read_text() != "")
        killed.append(int(pid_file.read_text()))
        os.kill(killed[0], signal.SIGKILL)

    killer = threading.Thread(target=kill_the_worker)
    killer.start()
    result = pool.submit(problem)
    killer.join()
    assert killed, "the task never reported its pid"
    # An error at the crash, not a timeout at the end of the 20 s budget.
    assert result.status is PlannerStatus.ERROR and "crashed" in result.message
    assert pool.submit(make_problem(tmp_path, scene="next")).solved


def test_concurrent_victims_of_one_crash_rebuild_the_pool_once(tmp_path: Path) -> None:
    with make_local_pool(processes=3) as pool:
        problems = [make_problem(tmp_path, scene=f"slow-{i}", sleep=1.0) for i in range(2)]
        problems.append(make_problem(tmp_path, scene="crash", sleep=0.3, exit=True))
        results = submit_all(pool, problems)
        assert results[2].status is PlannerStatus.ERROR
        assert (pool.stats().crashes, pool.stats().recycles) == (1, 1)
        assert pool.submit(make_problem(tmp_path, scene="next")).solved


# --- coalescing ---


def test_identical_concurrent_requests_plan_once(pool: PlannerPool, tmp_path: Path) -> None:
    results = submit_all(pool, [make_problem(tmp_path, sleep=1.0)] * 8)
    assert runs(tmp_path) == 1
    assert all(r is results[0] for r in results)
    assert results[0].solved
    assert (pool.stats().coalesced, pool.stats().completed) == (7, 1)


def test_near_identical_starts_coalesce(pool: PlannerPool, tmp_path: Path) -> None:
    problems = [make_problem(tmp_path, start=(0.0 + 1e-5 * i, 0.0), sleep=1.0) for i in range(4)]
    results = submit_all(pool, problems)
    assert runs(tmp_path) == 1
    assert all(r.solved for r in results)


def test_different_starts_do_not_coalesce(pool: PlannerPool, tmp_path: Path) -> None:
    problems = [make_problem(tmp_path, start=(0.01 * i, 0.0), sleep=0.5) for i in range(2)]
    results = submit_all(pool, problems)
    assert runs(tmp_path) == 2
    assert [r.path[0][0] for r in results if r.path is not None] == [0.0, 0.01]
    assert pool.stats().coalesced == 0


def test_coalescing_key() -> None:
    base = make_problem(Path("/tmp"), start=(0.1, 0.2))
    near = make_problem(Path("/tmp"), start=(0.1 + 2e-4, 0.2 - 2e-4))
    assert coalescing_key(base) == coalescing_key(near)
    for other in (
        make_problem(Path("/tmp"), start=(0.102, 0.2)),
        make_problem(Path("/tmp"), start=(0.1, 0.2), scene="scene-b"),
        make_problem(Path("/tmp"), start=(0.1, 0.2), goal=(1.0, 0.99)),
    ):
        assert coalescing_key(other) != coalescing_key(base)


# --- negative cache ---


@pytest.mark.parametrize("status", ["timeout", "uncertified", "invalid_start", "invalid_goal"])
def test_failed_query_fails_fast_until_the_ttl(tmp_path: Path, status: str) -> None:
    clock = FakeClock()
    with make_local_pool(ttl=30.0, clock=clock) as pool:
        first = pool.submit(replace(make_problem(tmp_path, status=status), seed=7))
        assert first.status.value == status and runs(tmp_path) == 1
        clock.advance(29.9)
        second = pool.submit(replace(make_problem(tmp_path, status=status), seed=8))
        assert second.status.value == status and "negative cache" in second.message
        assert "failed 29.9 s ago" in second.message
        assert second.seed == 7  # the seed of the run that failed, to reproduce it
        assert runs(tmp_path) == 1 and pool.stats().negative_hits == 1  # not planned again
        assert pool.submit(make_problem(tmp_path, scene="other", status=status)).status.value == (
            status
        )
        assert runs(tmp_path, "other") == 1  # another scene is another query
        clock.advance(0.1)  # the ttl is over
        pool.submit(make_problem(tmp_path, status=status))
        assert runs(tmp_path) == 2


def test_errors_are_not_negatively_cached(pool: PlannerPool, tmp_path: Path) -> None:
    for _ in range(2):
        assert pool.submit(make_problem(tmp_path, status="error")).status is PlannerStatus.ERROR
    assert pool.submit(make_problem(tmp_path, scene="crash", exit=True)).status is (
        PlannerStatus.ERROR
    )
    assert pool.submit(make_problem(tmp_path, scene="crash", exit=True)).status is (
        PlannerStatus.ERROR
    )
    assert runs(tmp_path) == 2 and runs(tmp_path, "crash") == 2
    assert pool.stats().negative_hits == 0


@pytest.mark.parametrize("status", ["timeout", "uncertified"])
def test_a_longer_budget_retries_a_query_that_ran_out_of_budget(
    pool: PlannerPool, tmp_path: Path, status: str
) -> None:
    pool.submit(make_problem(tmp_path, status=status, budget_s=1.0))
    pool.submit(make_problem(tmp_path, status=status, budget_s=1.0))
    assert runs(tmp_path) == 1
    pool.submit(make_problem(tmp_path, status=status, budget_s=2.0))
    assert runs(tmp_path) == 2


def test_a_timeout_after_waiting_for_a_worker_is_not_remembered(tmp_path: Path) -> None:
    backend = LocalBackend(scripted_task, processes=1)
    with PlannerPool(backend, negative_cache_ttl_s=30.0, overhead_s=1.0) as pool:
        assert backend.wait_ready(60.0)
        busy = threading.Thread(target=pool.submit, args=(make_problem(tmp_path, sleep=1.5),))
        busy.start()
        assert wait_until(lambda: runs(tmp_path) == 1)  # the only worker has started the busy task
        # Given 1 s + 1 s overhead, the late task waits ~1.5 s for the worker (more than the
        # overhead), then runs 1 s: it overruns with only ~0.5 s of its budget left.
        late = make_problem(tmp_path, scene="late", sleep=1.0, budget_s=1.0)
        first = pool.submit(late)
        busy.join()
        assert first.status is PlannerStatus.TIMEOUT, first.message
        assert first.stats["queued_s"] > 1.0
        second = pool.submit(late)  # a free worker and the whole budget: planned again
        assert second.status is PlannerStatus.SOLVED and "negative cache" not in second.message
        assert pool.stats().negative_hits == 0


def test_zero_ttl_disables_the_negative_cache(tmp_path: Path) -> None:
    with make_local_pool(ttl=0.0) as pool:
        for _ in range(2):
            pool.submit(make_problem(tmp_path, status="timeout"))
        assert runs(tmp_path) == 2


# --- lifecycle and configuration ---


def test_closed_pool_answers_with_an_error(tmp_path: Path) -> None:
    pool = make_local_pool()
    pool.close()
    result = pool.submit(make_problem(tmp_path))
    assert result.status is PlannerStatus.ERROR and "closed" in result.message
    assert runs(tmp_path) == 0


def test_a_closed_pool_leaves_no_semaphore_to_the_resource_tracker() -> None:
    """A process killed right after closing its pool (as uvicorn's server processes are, by the
    SIGTERM they raise again once shut down) has released its queues' semaphores already."""
    code = (
        "import os, signal\n"
        "from tests.jobs.test_pool import scripted_task\n"
        "from trajcache.jobs.local import LocalBackend\n"
        "backend = LocalBackend(scripted_task, processes=2)\n"
        "assert backend.wait_ready(120.0)\n"
        "backend.close()\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    root = Path(__file__).resolve().parents[2]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]),
    }
    # Read until every holder of stderr, the resource tracker last, has exited.
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True, timeout=240
    )
    assert done.returncode == -signal.SIGKILL, done.stderr[-3000:]
    assert "leaked" not in done.stderr and "resource_tracker" not in done.stderr, done.stderr


def test_budget_is_capped_by_the_settings(tmp_path: Path) -> None:
    settings = Settings(worker_processes=1, plan_budget_s=0.2, plan_budget_max_s=0.3)
    with make_pool(settings, task_fn=scripted_task) as pool:
        assert isinstance(pool.backend, LocalBackend) and pool.backend.processes == 1
        result = pool.submit(make_problem(tmp_path, budget_s=10.0, sleep=3.0))
        # Given up after the capped budget and the overhead, before the 3 s task finished.
        assert result.status is PlannerStatus.TIMEOUT, result.message
        assert "budget of 0.3 s (no answer after 1.3 s)" in result.message


def test_real_planner_through_make_pool() -> None:
    with make_pool(Settings(worker_processes=1)) as pool:  # the default task: run_planning
        assert isinstance(pool.backend, LocalBackend) and pool.backend.wait_ready(30.0)
        solved = pool.submit(two_link_problem((2.0, 1.0)))
        assert solved.solved, solved.message
        assert solved.path is not None
        assert np.allclose(solved.path[[0, -1]], [[0.0, 0.0], [2.0, 1.0]])
        blocked = pool.submit(two_link_problem((1.5708, 0.0)))  # the arm would be in the wall
        assert blocked.status is PlannerStatus.INVALID_GOAL, blocked.message
        again = pool.submit(two_link_problem((1.5708, 0.0)))
        assert again.status is PlannerStatus.INVALID_GOAL and "negative cache" in again.message


def test_make_pool_picks_the_celery_backend() -> None:
    from trajcache.jobs.celery_app import CeleryBackend

    settings = Settings(worker_backend="celery", celery_broker_url="redis://127.0.0.1:1/0")
    with make_pool(settings) as pool:
        assert isinstance(pool.backend, CeleryBackend)
    with pytest.raises(ValueError, match="task_fn"):
        make_pool(settings, task_fn=scripted_task)


def test_recycling_lets_the_other_requests_finish(tmp_path: Path) -> None:
    with make_local_pool(grace=0.3) as pool:
        stuck = make_problem(tmp_path, scene="stuck", budget_s=0.3, sleep=6.0)
        # a budget far above its 2.5 s, so that only the recycle could make it fail
        innocent = make_problem(tmp_path, scene="innocent", budget_s=15.0, sleep=2.5)
        results = submit_all(pool, [stuck, innocent])
        assert results[0].status is PlannerStatus.TIMEOUT
        assert results[1].solved, results[1].message
        assert pool.stats().recycles == 1
