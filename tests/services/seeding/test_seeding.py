"""Seed jobs below the API: the request format, progress counting, leases, running, resuming."""

from __future__ import annotations

import math
import threading
from datetime import timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sqlalchemy as sa
from pydantic import ValidationError

from tests.robots import TWO_JOINT_URDF
from tests.services.seeding.conftest import register_two_joint
from tests.waiting import SOLVABLE, wait_until
from trajcache.core.config import Settings
from trajcache.db.models import PlanEvent, SeedJob, Trajectory, utcnow
from trajcache.reference.cleaning import cleaning_run
from trajcache.reference.robot import reference_model
from trajcache.services.catalog.trajectories import NewTrajectory, store_trajectory
from trajcache.services.context import ServiceContext
from trajcache.services.errors import (
    ConflictError,
    InvalidInputError,
    NotFoundError,
    PayloadTooLargeError,
)
from trajcache.services.seeding.jobs import (
    cancel_job,
    claim_job,
    claimable_jobs,
    create_job,
    get_job,
    list_jobs,
)
from trajcache.services.seeding.runner import MAX_ERRORS, JobRun, Outcome, Progress, _collect
from trajcache.services.seeding.scheduler import SeedScheduler
from trajcache.services.seeding.spec import SeedJobSpec
from trajcache.services.seeding.work import expand

SETTINGS = Settings()
STOW = [0.0, -0.6, 0.0, 0.4, 0.0, 1.0, 0.0]
START = [1.0, 1.0, 0.0, *STOW]
GOAL = [1.0, 1.0, 0.0, 0.3, -0.4, 0.0, 0.6, 0.0, 1.0, 0.0]
SPHERE = {"id": "ball", "type": "sphere", "size": [0.1], "pose": {"position": [3, 3, 1]}}


def spec(**fields: Any) -> SeedJobSpec:
    return SeedJobSpec.model_validate({"model_id": "m", **fields})


def work_of(**fields: Any) -> Any:
    return expand(spec(**fields), model=reference_model(), settings=SETTINGS)


def detail(exc: pytest.ExceptionInfo[BaseException]) -> str:
    return str(exc.value)


# --- the request format -----------------------------------------------------------------------


def test_scenes_times_queries_scene_major() -> None:
    work = work_of(
        scenes=[{"objects": [SPHERE]}, {"generator": "restroom", "doors_deg": 45}],
        queries=[{"start": START, "goal": GOAL}, {"start": GOAL, "goal": START, "scene": 1}],
    )
    assert len(work.scenes) == 2
    assert [o.id for o in work.scenes[0].objects] == ["ball"]
    assert work.scenes[1].env["stall_2_door"] == pytest.approx(math.radians(45))
    assert [(i.scene, i.label) for i in work.items] == [
        (0, "scene 0, query 0"),
        (1, "scene 1, query 0"),
        (1, "scene 1, query 1"),
    ]
    np.testing.assert_allclose(work.items[2].start, GOAL)


def test_explicit_base_with_patch_variants() -> None:
    base = {"objects": [SPHERE], "env": {"door": 0.0}}
    work = work_of(
        base_scene=base,
        variants=[{}, {"remove": ["ball"], "env": {"door": 0.5}}],
        queries=[{"start": START, "goal": GOAL}],
    )
    assert [len(s.objects) for s in work.scenes] == [1, 0]
    assert [s.env["door"] for s in work.scenes] == [0.0, 0.5]
    with pytest.raises(InvalidInputError) as exc:
        work_of(
            base_scene=base,
            variants=[{}, {"remove": ["ghost"]}],
            queries=[{"start": START, "goal": GOAL}],
        )
    assert "variants[1]" in detail(exc) and "ghost" in detail(exc)


def test_generator_sweep_over_door_angles_and_env_values() -> None:
    work = work_of(
        base_scene={"generator": "restroom", "seats_deg": 90},
        sweep={"param": "doors_deg", "start": 0, "stop": 90, "step": 30},
        queries=[{"start": START, "goal": GOAL}],
    )
    doors = [s.env["stall_1_door"] for s in work.scenes]
    assert doors == pytest.approx([math.radians(a) for a in (0, 30, 60, 90)])
    assert all(s.env["stall_3_seat"] == pytest.approx(math.pi / 2) for s in work.scenes)
    assert len({s.hash for s in work.scenes}) == 4

    by_env = work_of(
        base_scene={"generator": "restroom"},
        sweep={"param": "env.stall_2_door", "start": 0.0, "stop": 1.0, "step": 0.5},
        queries=[{"start": START, "goal": GOAL}],
    )
    assert [s.env["stall_2_door"] for s in by_env.scenes] == pytest.approx([0.0, 0.5, 1.0])
    assert all(s.env["stall_1_door"] == 0.0 for s in by_env.scenes)


def test_generator_variants_override_the_base() -> None:
    work = work_of(
        base_scene={"generator": "restroom", "doors_deg": [10, 20, 30], "env": {"stall_1_seat": 1}},
        variants=[{"env": {"stall_2_door": 0.5}}, {"doors_deg": 80}],
        queries=[{"start": START, "goal": GOAL}],
    )
    first, second = work.scenes
    assert first.env["stall_1_door"] == pytest.approx(math.radians(10))
    assert first.env["stall_2_door"] == pytest.approx(0.5)
    assert first.env["stall_1_seat"] == pytest.approx(1.0)
    assert second.env["stall_3_door"] == pytest.approx(math.radians(80))
    assert second.env["stall_1_seat"] == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("fields", "needles"),
    [
        (
            {"scenes": [{"generator": "restroom", "env": {"stall_9_door": 0.1}}]},
            ["scenes[0].env", "stall_9_door", "stall_1_door"],
        ),
        ({"scenes": [{"generator": "restroom", "doors_deg": 120}]}, ["scenes[0]", "0..90"]),
        ({"scenes": [{"generator": "kitchen"}]}, ["scenes[0].generator", "kitchen"]),
        ({"scenes": [{"generator": "restroom", "doors_deg": [1, 2]}]}, ["doors_deg", "3"]),
        ({"scenes": [{"generator": "restroom", "lamp": 1}]}, ["scenes[0]", "lamp"]),
        (
            {"scenes": [{"generator": "restroom", "doors_dge": 10}]},
            ["scenes[0]: doors_dge: unknown field 'doors_dge' (did you mean 'doors_deg'?)"],
        ),
        (
            {"scenes": [{"generator": "restroom", "env": {"stall_1_dor": 0.1}}]},
            ["unknown value 'stall_1_dor' (did you mean 'stall_1_door'?)"],
        ),
        ({"scenes": [{}, {"objects": [{"id": "a", "type": "box"}]}]}, ["scenes[1]", "size"]),
        (
            {
                "base_scene": {"objects": []},
                "sweep": {"param": "doors_deg", "start": 0, "stop": 1, "step": 1},
            },
            ["sweep needs a generator"],
        ),
        (
            {
                "base_scene": {"generator": "restroom"},
                "sweep": {"param": "height", "start": 0, "stop": 1, "step": 1},
            },
            ["sweep.param", "height"],
        ),
    ],
)
def test_bad_scenes_are_named(fields: dict[str, Any], needles: list[str]) -> None:
    with pytest.raises(InvalidInputError) as exc:
        work_of(**fields, queries=[{"start": START, "goal": GOAL}])
    for needle in needles:
        assert needle in detail(exc)


@pytest.mark.parametrize(
    ("query", "needles"),
    [
        ({"start": START[:3], "goal": GOAL}, ["queries[0].start", "3 values", "expected 10"]),
        ({"start": START, "goal": [*GOAL[:4], 3.0, *GOAL[5:]]}, ["queries[0].goal", "joint2"]),
        ({"start": START, "goal": GOAL, "scene": 4}, ["queries[0].scene", "0..0"]),
    ],
)
def test_bad_queries_are_named(query: dict[str, Any], needles: list[str]) -> None:
    with pytest.raises(InvalidInputError) as exc:
        work_of(scenes=[{"objects": []}], queries=[query])
    for needle in needles:
        assert needle in detail(exc)


def test_sizes_are_bounded_by_the_settings() -> None:
    small = Settings(seed_max_scenes=3, seed_max_queries=5)
    with pytest.raises(PayloadTooLargeError, match="seed_max_scenes=3"):
        expand(
            spec(
                base_scene={"generator": "restroom"},
                sweep={"param": "doors_deg", "start": 0, "stop": 90, "step": 30},
                queries=[{"start": START, "goal": GOAL}],
            ),
            model=reference_model(),
            settings=small,
        )
    with pytest.raises(PayloadTooLargeError, match="seed_max_queries=5"):
        expand(
            spec(scenes=[{}, {}], queries=[{"start": START, "goal": GOAL}] * 3),
            model=reference_model(),
            settings=small,
        )
    with pytest.raises(PayloadTooLargeError, match="max_scene_objects=1"):
        expand(
            spec(
                scenes=[{"objects": [SPHERE, {**SPHERE, "id": "b"}]}],
                queries=[{"start": START, "goal": GOAL}],
            ),
            model=reference_model(),
            settings=Settings(max_scene_objects=1),
        )


def test_options_and_concurrency_are_bounded() -> None:
    with pytest.raises(InvalidInputError, match=r"options\.budget_s"):
        work_of(scenes=[{}], queries=[{"start": START, "goal": GOAL}], options={"budget_s": 99})
    with pytest.raises(InvalidInputError, match="seed_concurrency=2"):
        work_of(scenes=[{}], queries=[{"start": START, "goal": GOAL}], concurrency=3)


@pytest.mark.parametrize(
    ("fields", "needle"),
    [
        ({"scenes": [{}]}, "either queries or a workload"),
        ({"workload": {"name": "cleaning"}, "queries": [{"start": [0], "goal": [0]}]}, "either"),
        ({"workload": {"name": "cleaning"}, "scenes": [{}]}, "brings its own scenes"),
        ({"queries": [{"start": [0], "goal": [0]}]}, "either scenes or a base_scene"),
        (
            {"scenes": [{}], "variants": [{}], "queries": [{"start": [0], "goal": [0]}]},
            "need a base",
        ),
        ({"workload": {"name": "cleaning", "doors_deg": [10]}}, "door_sweep"),
        ({"workload": {"name": "mopping"}}, "workload.name"),
    ],
)
def test_the_request_takes_one_form(fields: dict[str, Any], needle: str) -> None:
    with pytest.raises(ValidationError) as exc:
        spec(**fields)
    assert needle in str(exc.value)


def test_cleaning_workload_plans_each_call_in_its_scene() -> None:
    work = work_of(workload={"name": "cleaning", "seed": 3})
    run = cleaning_run(3)
    assert len(work.items) == len(run.calls) > 200
    for item, call in zip(work.items, run.calls, strict=True):
        assert work.scenes[item.scene].hash == run.scene_for(call).hash
        np.testing.assert_array_equal(item.start, call.start)
        assert call.label in item.label
    limited = work_of(workload={"name": "cleaning", "seed": 3, "limit": 5})
    assert len(limited.items) == 5


def test_door_sweep_workload_is_one_run_per_angle() -> None:
    work = work_of(
        workload={
            "name": "door_sweep",
            "seed": 1,
            "doors_deg": {"start": 0, "stop": 90, "step": 45},
            "limit": 4,
        }
    )
    assert len(work.items) == 12
    doors = [round(math.degrees(work.scenes[i.scene].env["stall_1_door"])) for i in work.items]
    assert doors == [0] * 4 + [45] * 4 + [90] * 4
    assert work.items[4].label.startswith("doors 45°, call 0:")
    with pytest.raises(InvalidInputError, match=r"doors_deg\[1\]"):
        work_of(workload={"name": "door_sweep", "doors_deg": [10, 95]})


def test_workload_needs_a_model_of_the_reference_shape() -> None:
    from trajcache.geometry.model.urdf import load_robot_model

    arm = load_robot_model(TWO_JOINT_URDF)
    with pytest.raises(InvalidInputError, match="reference robot"):
        expand(spec(workload={"name": "cleaning", "limit": 2}), model=arm, settings=SETTINGS)


# --- progress over a finished prefix --------------------------------------------------------


def test_progress_counts_only_a_finished_prefix() -> None:
    progress = Progress(done=2, hits=1, planned=1, failed=0)
    finished = {3: Outcome("hit"), 4: Outcome("failed", "boom")}
    progress.absorb(finished, str)
    assert (progress.done, progress.hits) == (2, 1)  # item 2 is still running
    finished[2] = Outcome("planned", stored=True)
    progress.absorb(finished, lambda i: f"item {i}")
    assert (progress.done, progress.hits, progress.planned, progress.failed) == (5, 2, 2, 1)
    assert progress.stored == 1
    progress.absorb({5: Outcome("planned", stored=False)}, str)  # identical to a stored path
    assert (progress.planned, progress.stored, progress.values()["stored"]) == (3, 1, 1)
    old = Progress(done=0, hits=0, planned=0, failed=0, stored=None)  # begun before the counter
    old.absorb({0: Outcome("planned", stored=True)}, str)
    assert (old.planned, old.stored) == (1, None)
    assert progress.errors == [{"index": 4, "label": "item 4", "reason": "boom"}]
    assert finished == {}
    many = {i: Outcome("failed", f"r{i}") for i in range(6, 6 + MAX_ERRORS + 3)}
    progress.absorb(many, str)
    assert len(progress.errors) == MAX_ERRORS
    assert progress.errors[-1]["index"] == 5 + MAX_ERRORS + 3


# --- jobs in the database -------------------------------------------------------------------


def arm_job(model_id: str, goals: list[list[float]], **fields: Any) -> SeedJobSpec:
    scene = {
        "objects": [
            {"id": "far", "type": "sphere", "size": [0.05], "pose": {"position": [2, 2, 2]}}
        ]
    }
    queries = [{"start": [0.0, 0.0], "goal": g} for g in goals]
    return SeedJobSpec.model_validate(
        {"model_id": model_id, "scenes": [scene], "queries": queries, **fields}
    )


def queue(ctx: ServiceContext, job: SeedJobSpec) -> int:
    with ctx.sessions() as session:
        return create_job(session=session, ctx=ctx, spec=job).id


def row(ctx: ServiceContext, job_id: int) -> SeedJob:
    with ctx.sessions() as session:
        return get_job(session=session, job_id=job_id)


def wait_for(ctx: ServiceContext, job_id: int, timeout_s: float = 60.0) -> SeedJob:
    finished = wait_until(
        lambda: row(ctx, job_id).state not in ("queued", "running"), timeout_s=timeout_s
    )
    job = row(ctx, job_id)
    assert finished, f"job {job_id} still {job.state} after {timeout_s} s"
    return job


def events(ctx: ServiceContext, job_id: int) -> int:
    ctx.records.flush()  # plan bookkeeping is written off the request path
    with ctx.sessions() as session:
        return int(
            session.scalar(
                sa.select(sa.func.count()).where(PlanEvent.robot_id == f"seed-job-{job_id}")
            )
            or 0
        )


def test_create_validates_against_the_model(ctx: ServiceContext, model_id: str) -> None:
    with pytest.raises(NotFoundError, match="robot model"):
        queue(ctx, arm_job("f" * 64, [[0.5, 0.5]]))
    with pytest.raises(InvalidInputError, match=r"queries\[1\].goal.*elbow"):
        queue(ctx, arm_job(model_id, [[0.5, 0.5], [0.5, 2.5]]))
    job_id = queue(ctx, arm_job(model_id, [[0.5, 0.5], [0.4, 0.1]], name="two"))
    job = row(ctx, job_id)
    assert (job.state, job.total, job.done, job.name) == ("queued", 2, 0, "two")
    assert job.spec["queries"][1]["goal"] == [0.4, 0.1]


def test_claims_have_one_winner_until_the_lease_runs_out(
    ctx: ServiceContext, model_id: str
) -> None:
    job_id = queue(ctx, arm_job(model_id, [[0.5, 0.5]]))
    with ctx.sessions() as session:
        assert claimable_jobs(session=session, limit=10) == [job_id]
        assert claim_job(session=session, job_id=job_id, owner="a", lease_s=30)
        assert not claim_job(session=session, job_id=job_id, owner="b", lease_s=30)
        assert claimable_jobs(session=session, limit=10) == []
        session.execute(sa.update(SeedJob).values(lease_expires_at=utcnow() - timedelta(seconds=1)))
        session.commit()
        assert claimable_jobs(session=session, limit=10) == [job_id]
        assert claim_job(session=session, job_id=job_id, owner="b", lease_s=30)
    job = row(ctx, job_id)
    assert (job.state, job.lease_owner) == ("running", "b")
    assert job.started_at is not None


def test_concurrent_claims_of_one_job(ctx: ServiceContext, model_id: str) -> None:
    job_id = queue(ctx, arm_job(model_id, [[0.5, 0.5]]))
    wins: list[str] = []
    barrier = threading.Barrier(6)

    def claim(owner: str) -> None:
        with ctx.sessions() as session:
            barrier.wait()
            if claim_job(session=session, job_id=job_id, owner=owner, lease_s=30):
                wins.append(owner)

    threads = [threading.Thread(target=claim, args=(f"r{i}",)) for i in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(wins) == 1
    assert row(ctx, job_id).lease_owner == wins[0]


def test_cancel_is_idempotent_and_finished_jobs_refuse(ctx: ServiceContext, model_id: str) -> None:
    job_id = queue(ctx, arm_job(model_id, [[0.5, 0.5]]))
    with ctx.sessions() as session:
        assert cancel_job(session=session, job_id=job_id).state == "cancelled"
        assert cancel_job(session=session, job_id=job_id).state == "cancelled"
        assert not claim_job(session=session, job_id=job_id, owner="a", lease_s=30)
        with pytest.raises(NotFoundError):
            cancel_job(session=session, job_id=999)
        other = create_job(session=session, ctx=ctx, spec=arm_job(model_id, [[0.5, 0.5]])).id
        session.execute(sa.update(SeedJob).where(SeedJob.id == other).values(state="completed"))
        session.commit()
        with pytest.raises(ConflictError, match="already completed"):
            cancel_job(session=session, job_id=other)
        jobs, total = list_jobs(session=session, state="cancelled", limit=10)
        assert (total, [j.id for j in jobs]) == (1, [job_id])
        jobs, total = list_jobs(session=session, model_id=model_id, limit=10)
        assert [j.id for j in jobs] == [other, job_id]


def test_a_job_runs_hits_and_misses(ctx: ServiceContext, model_id: str) -> None:
    with ctx.sessions() as session:
        from trajcache.services.catalog.models import get_model

        model = get_model(session=session, registry=ctx.models, model_id=model_id)
        store_trajectory(
            session=session,
            settings=Settings(),
            trajectory=NewTrajectory(model=model, states=[[0.0, 0.0], [0.5, 0.5]], source="real"),
        )
    goals = [[0.5, 0.5], [0.52, 0.48], [-1.0, 1.0]]  # two near the stored one, one far away
    job_id = queue(ctx, arm_job(model_id, goals))
    scheduler = SeedScheduler(ctx).start()
    try:
        job = wait_for(ctx, job_id)
    finally:
        scheduler.stop()
    assert (job.state, job.done, job.hits, job.planned, job.failed) == ("completed", 3, 2, 0, 1)
    assert job.errors[0]["index"] == 2 and "miss" in job.errors[0]["reason"]
    assert job.lease_owner is None and job.finished_at is not None
    assert events(ctx, job_id) == 3


def test_a_job_orphaned_by_a_crash_resumes_from_its_progress(
    ctx: ServiceContext, model_id: str
) -> None:
    goals = [[0.1 * k, -0.05 * k] for k in range(10)]
    job_id = queue(ctx, arm_job(model_id, goals))
    with ctx.sessions() as session:  # a replica claimed it, did 4 items, and died
        assert claim_job(session=session, job_id=job_id, owner="dead", lease_s=30)
        session.execute(
            sa.update(SeedJob)
            .where(SeedJob.id == job_id)
            .values(done=4, failed=4, lease_expires_at=utcnow() - timedelta(seconds=1))
        )
        session.commit()
    scheduler = SeedScheduler(ctx).start()
    try:
        job = wait_for(ctx, job_id)
    finally:
        scheduler.stop()
    assert (job.state, job.done, job.failed) == ("completed", 10, 10)
    assert events(ctx, job_id) == 6  # only the items after the progress were planned


def test_a_live_lease_is_not_taken_over(ctx: ServiceContext, model_id: str) -> None:
    job_id = queue(ctx, arm_job(model_id, [[0.5, 0.5]]))
    with ctx.sessions() as session:
        assert claim_job(session=session, job_id=job_id, owner="alive", lease_s=30)
    scheduler = SeedScheduler(ctx)
    assert scheduler.poll() == []
    assert row(ctx, job_id).lease_owner == "alive"


def test_a_stored_job_that_no_longer_expands_fails(ctx: ServiceContext, model_id: str) -> None:
    job_id = queue(ctx, arm_job(model_id, [[0.5, 0.5]]))
    with ctx.sessions() as session:
        session.execute(sa.update(SeedJob).where(SeedJob.id == job_id).values(total=7))
        session.commit()
    scheduler = SeedScheduler(ctx).start()
    try:
        job = wait_for(ctx, job_id)
    finally:
        scheduler.stop()
    assert job.state == "failed"
    assert "expands to 1 requests, not 7" in (job.message or "")


def test_planned_results_are_stored_as_sim_with_scene_and_env(
    migrated_url: str, tmp_path: Path
) -> None:
    context = ServiceContext.create(
        Settings(database_url=migrated_url, worker_processes=1, seed_heartbeat_s=0.1, **SOLVABLE)
    )
    try:
        model = register_two_joint(context)
        scene = {
            "objects": [
                {
                    "id": "post",
                    "type": "box",
                    "size": [0.1, 0.1, 0.1],
                    "pose": {"position": [1, 1, 0]},
                }
            ],
            "env": {"door": 0.25},
        }
        job_id = queue(
            context,
            SeedJobSpec.model_validate(
                {
                    "model_id": model.model_id,
                    "scenes": [scene],
                    "queries": [{"start": [0, 0], "goal": [1.0, 0.5]}],
                }
            ),
        )
        scheduler = SeedScheduler(context).start()
        try:
            job = wait_for(context, job_id, timeout_s=180)
        finally:
            scheduler.stop()
        assert (job.state, job.planned, job.stored, job.failed) == ("completed", 1, 1, 0), job
        with context.sessions() as session:
            stored = session.scalars(sa.select(Trajectory)).all()
        assert [(t.source, t.env) for t in stored] == [("sim", {"door": 0.25})]
        from trajcache.geometry.scene.parse import parse_scene

        assert stored[0].scene_hash == parse_scene(scene).hash
    finally:
        context.close()


@pytest.mark.redis
def test_misses_go_through_celery_workers_when_configured(
    migrated_url: str, tmp_path: Path
) -> None:
    import sys
    import uuid

    from tests.conftest import REDIS_URL, require_service
    from tests.jobs.test_celery import start_worker

    require_service("Redis", "127.0.0.1", 6379)
    queue = f"seed-test-{uuid.uuid4().hex[:8]}"
    command = [sys.executable, "-m", "celery", "-A", "trajcache.jobs.celery_app", "worker"]
    command += ["--pool=solo", "-Q", queue, "-n", f"{queue}@%h", "--without-gossip"]
    command += ["--without-mingle", "--without-heartbeat"]
    # The worker reads the job's model from the service's database.
    worker, probe = start_worker(command, queue, tmp_path, task_fn=None, database_url=migrated_url)
    probe.close()
    context = ServiceContext.create(
        Settings(
            database_url=migrated_url,
            worker_backend="celery",
            celery_broker_url=REDIS_URL,
            celery_result_backend=REDIS_URL,
            celery_queue=queue,
            seed_heartbeat_s=0.1,
            **SOLVABLE,
        )
    )
    try:
        model = register_two_joint(context)
        job_id = queue_of(context, model.model_id)
        scheduler = SeedScheduler(context).start()
        try:
            job = wait_for(context, job_id, timeout_s=120)
        finally:
            scheduler.stop()
        assert (job.state, job.planned, job.failed) == ("completed", 1, 0), job.errors
        pool = context.planner_pool()
        assert pool is not None and type(pool.backend).__name__ == "CeleryBackend"
        assert pool.stats().solved == 1
    finally:
        context.close()
        worker.stop()


def queue_of(ctx: ServiceContext, model_id: str) -> int:
    return queue(
        ctx,
        SeedJobSpec.model_validate(
            {
                "model_id": model_id,
                "scenes": [{}],
                "queries": [{"start": [0, 0], "goal": [1.0, -0.5]}],
            }
        ),
    )


def test_a_stop_during_retries_leaves_the_item_to_be_run_again(migrated_url: str) -> None:
    context = ServiceContext.create(Settings(database_url=migrated_url, worker_processes=1))
    try:
        model = register_two_joint(context)
        pool = context.planner_pool()
        assert pool is not None
        pool.close()  # every miss now ends with status `error`, which is retried
        job = SeedJobSpec.model_validate(
            {
                "model_id": model.model_id,
                "scenes": [{}],
                "queries": [{"start": [0, 0], "goal": [1, 1]}],
            }
        )
        work = expand(job, model=model, settings=context.settings)
        run = JobRun(context, 1, "me", on_exit=lambda _i: None)
        attempts: list[Outcome] = []
        attempted = threading.Event()
        attempt = run._attempt

        def counted(*args: Any) -> Outcome:
            attempts.append(attempt(*args))
            attempted.set()
            return attempts[-1]

        run._attempt = counted  # type: ignore[method-assign]
        outcomes: list[Outcome] = []
        worker = threading.Thread(target=lambda: outcomes.append(run._plan_one(job, work, 0)))
        worker.start()
        assert attempted.wait(10)  # the first attempt failed; it waits to retry
        run.shut_down()
        worker.join(10)
        assert outcomes == [Outcome("skipped")]
        assert [a.kind for a in attempts] == ["error"]  # the stop ended the wait: no retry ran
        from concurrent.futures import Future

        done: Future[Outcome] = Future()
        done.set_result(outcomes[0])
        finished: dict[int, Outcome] = {}
        _collect(finished, 0, done)
        assert finished == {}  # not counted: a resumed job runs it again
    finally:
        context.close()
