"""The cache-hit plan flow: few queries, the validation memo kept safe, bookkeeping recorded."""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np
import pytest
import sqlalchemy as sa

from tests.services.hit_setup import context, count_statements, store, two_joint
from trajcache.cache.memo import MemoUse
from trajcache.db.models import PlanEvent, Trajectory
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.scene.scene import make_scene
from trajcache.services.catalog.robots import put_robot, robot_scene
from trajcache.services.catalog.scene_writes import put_scene
from trajcache.services.context import ServiceContext
from trajcache.services.errors import NotFoundError
from trajcache.services.plan.flow import PlanAnswer, PlanRequest, PlanSource, plan

ARM_PATH = [[0.0, 0.0], [0.3, 0.2], [0.7, 0.2], [1.0, 0.0]]


def robot(ctx: ServiceContext, model: RobotModel, robot_id: str = "r1") -> str:
    with ctx.sessions() as session:
        put_robot(session=session, robot_id=robot_id, model_id=model.model_id)
    return robot_id


def set_scene(ctx: ServiceContext, robot_id: str, objects: list[dict[str, Any]]) -> str:
    scene = parse_scene({"objects": objects})
    with ctx.sessions() as session:
        _, scene_hash = put_scene(
            session=session, scenes=ctx.scenes, robot_id=robot_id, scene=scene
        )
    return scene_hash


def ask(
    ctx: ServiceContext,
    start: list[float],
    goal: list[float],
    robot_id: str = "r1",
    **options: Any,
) -> PlanAnswer:
    request = PlanRequest(
        start=np.asarray(start, float),
        goal=np.asarray(goal, float),
        **{"threshold": 0.2, "max_candidates": 3, "fallback": False, **options},
    )
    return plan(ctx=ctx, robot_id=robot_id, request=request)


def box(oid: str, position: list[float], size: float) -> dict[str, Any]:
    return {"id": oid, "type": "box", "size": [size] * 3, "pose": {"position": position}}


def upper_arm_point(shoulder: float, radius: float = 0.25) -> list[float]:
    """A point on the two-joint arm's upper link at `shoulder` (rad), `radius` up the link."""
    return [radius * math.sin(shoulder), 0.0, 0.1 + radius * math.cos(shoulder)]


def test_a_warm_hit_reads_the_database_once_and_writes_off_the_request_path(
    database_url: str,
) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        rid = robot(ctx, model)
        stored = store(ctx, model, ARM_PATH)
        ask(ctx, [0.01, 0.0], [1.0, 0.01])  # warms model, scene, index and key states
        ctx.records.flush()
        with count_statements(ctx.engine) as statements:
            answer = ask(ctx, [0.02, 0.0], [0.99, 0.0], rid)
        assert answer.source is PlanSource.CACHE and answer.trajectory_id == stored
        # the robot with its scene and the replica sync in one query; nothing is written before
        # answering
        assert len(statements) == 1, statements
        assert "robots" in statements[0] and "trajectory_tombstones" in statements[0]
        assert answer.record is not None
        assert ctx.records.wait(answer.record, timeout=10)
        with ctx.sessions() as session:
            row = session.get(Trajectory, stored)
            assert row is not None and row.hits == 2 and row.last_used_at is not None
            assert session.scalar(sa.select(sa.func.count()).select_from(PlanEvent)) == 2


def test_plan_events_are_durable_when_the_service_stops(database_url: str) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        robot(ctx, model)
        stored = store(ctx, model, ARM_PATH)
        ctx.records.linger_s = 30.0  # nothing is written before the service stops
        for i in range(20):
            assert ask(ctx, [0.001 * i, 0.0], [1.0, 0.0]).source is PlanSource.CACHE
    with context(database_url) as after, after.sessions() as session:
        events = session.execute(sa.select(PlanEvent).order_by(PlanEvent.id)).scalars().all()
        assert len(events) == 20
        assert all((e.status, e.source, e.trajectory_id) == ("success", "cache", stored)
                   for e in events)  # fmt: skip
        assert [e.created_at for e in events] == sorted(e.created_at for e in events)
        row = session.get(Trajectory, stored)
        assert row is not None and row.hits == 20


def test_an_exact_repeat_is_answered_from_the_memo_and_new_endpoints_check_only_ends(
    database_url: str,
) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        robot(ctx, model)
        store(ctx, model, ARM_PATH)
        first = ask(ctx, [0.02, 0.0], [0.98, 0.0])
        assert first.memo is MemoUse.NONE
        repeat = ask(ctx, [0.02, 0.0], [0.98, 0.0])
        assert repeat.memo is MemoUse.WHOLE and np.array_equal(repeat.states, first.states)
        moved = ask(ctx, [-0.03, 0.01], [1.04, -0.02])
        assert moved.memo is MemoUse.ENDS and moved.source is PlanSource.CACHE


def test_a_scene_change_is_validated_in_full_and_rejects_what_it_blocks(database_url: str) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        rid = robot(ctx, model)
        stored = store(ctx, model, ARM_PATH)
        assert ask(ctx, [0.02, 0.0], [0.98, 0.0]).memo is MemoUse.NONE
        assert ask(ctx, [0.02, 0.0], [0.98, 0.0]).memo is MemoUse.WHOLE
        # a small box in the sweep of the upper arm at shoulder 0.5, clear of both endpoints
        set_scene(ctx, rid, [box("blocker", upper_arm_point(0.5), 0.04)])
        answer = ask(ctx, [0.02, 0.0], [0.98, 0.0])
        assert answer.source is None and answer.trajectory_id is None
        assert answer.rejected[0]["trajectory_id"] == stored
        assert "blocker" in str(answer.rejected[0]["reason"])


def test_a_new_start_whose_first_segment_collides_is_rejected_despite_the_memo(
    database_url: str,
) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        rid = robot(ctx, model)
        store(ctx, model, ARM_PATH)
        # a box the stored path never reaches (shoulder −0.25); a start at −0.48 sweeps through it
        set_scene(ctx, rid, [box("post", upper_arm_point(-0.25), 0.02)])
        assert ask(ctx, [0.0, 0.0], [1.0, 0.0]).source is PlanSource.CACHE  # interior remembered
        assert ask(ctx, [0.0, 0.0], [1.0, 0.0]).memo is MemoUse.WHOLE
        answer = ask(ctx, [-0.48, 0.0], [1.0, 0.0], threshold=0.5)
        assert answer.source is None and "post" in str(answer.rejected[0]["reason"])
        free = ask(ctx, [0.1, 0.0], [1.0, 0.0], threshold=0.5)  # the same interior, a clear start
        assert free.source is PlanSource.CACHE and free.memo is MemoUse.ENDS


def test_a_re_anchored_base_moves_the_whole_path_and_is_validated_in_full(
    database_url: str,
) -> None:
    """Base re-anchoring: the same arm motion at another base pose is a new path."""
    with context(database_url) as ctx:
        model = two_joint(ctx, base="planar")
        rid = robot(ctx, model)
        path = [[0.0, 0.0, 0.0, *q] for q in ARM_PATH]
        store(ctx, model, path)
        # a box in the sweep of the upper arm at shoulder 0.5, for the base at x = 1 only
        blocker = upper_arm_point(0.5)
        set_scene(ctx, rid, [box("blocker", [blocker[0] + 1.0, *blocker[1:]], 0.04)])
        arm = {"arm_only": True}  # match on the arm joints: the base may be anywhere
        here = ask(ctx, [0.0, 0.0, 0.0, 0.02, 0.0], [0.0, 0.0, 0.0, 0.98, 0.0], **arm)
        assert here.source is PlanSource.CACHE
        again = ask(ctx, [0.0, 0.0, 0.0, -0.02, 0.01], [0.0, 0.0, 0.0, 1.01, 0.0], **arm)
        assert again.memo is MemoUse.ENDS  # same base: the re-anchored interior is the same
        there = ask(ctx, [0.1, 0.0, 0.0, 0.02, 0.0], [0.1, 0.0, 0.0, 0.98, 0.0], **arm)
        assert there.source is PlanSource.CACHE
        assert there.memo is MemoUse.NONE  # 10 cm away: the interior moved with the base
        blocked = ask(ctx, [1.0, 0.0, 0.0, 0.02, 0.0], [1.0, 0.0, 0.0, 0.98, 0.0], **arm)
        assert blocked.source is None and "blocker" in str(blocked.rejected[0]["reason"])


def test_identical_adapted_candidates_are_validated_once(database_url: str) -> None:
    """Two-state trajectories all adapt to the straight line from start to goal."""
    with context(database_url) as ctx:
        model = two_joint(ctx)
        rid = robot(ctx, model)
        ids = [store(ctx, model, [[0.0, d], [1.0, 0.0]]) for d in (0.0, 0.05, 0.1)]
        set_scene(ctx, rid, [box("blocker", upper_arm_point(0.5), 0.04)])
        answer = ask(ctx, [0.0, 0.0], [1.0, 0.0])
        assert answer.candidates_tried == 3 and answer.source is None
        assert sorted(r["trajectory_id"] for r in answer.rejected) == sorted(ids)
        first, *others = (r["reason"] for r in answer.rejected)
        assert "blocker" in str(first)
        # one validation's verdict is reused: the very same message object, not a second run
        assert all(reason is first for reason in others)


def test_concurrent_hits_all_answer_and_all_are_recorded(database_url: str) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        robot(ctx, model)
        stored = store(ctx, model, ARM_PATH)
        errors: list[str] = []

        def client(k: int) -> None:
            for i in range(10):
                answer = ask(ctx, [0.001 * k, 0.0], [1.0, 0.001 * i])
                if answer.source is not PlanSource.CACHE:
                    errors.append(answer.message)

        threads = [threading.Thread(target=client, args=(k,)) for k in range(8)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert not errors
        assert ctx.records.flush(timeout=10)
        with ctx.sessions() as session:
            row = session.get(Trajectory, stored)
            assert row is not None and row.hits == 80
            assert session.scalar(sa.select(sa.func.count()).select_from(PlanEvent)) == 80


def test_robot_scene_is_one_query_once_the_scene_is_parsed(database_url: str) -> None:
    with context(database_url) as ctx:
        model = two_joint(ctx)
        rid = robot(ctx, model)
        with ctx.sessions() as session:
            bare = robot_scene(session=session, scenes=ctx.scenes, robot_id=rid)
        assert (bare.model_id, bare.version, bare.scene.hash) == (
            model.model_id, 0, make_scene([], {}).hash
        )  # fmt: skip
        scene_hash = set_scene(ctx, rid, [box("table", [0.5, 0.0, 0.0], 0.2)])
        ctx.scenes = type(ctx.scenes)()  # a replica that has not parsed this version yet
        with ctx.sessions() as session, count_statements(ctx.engine) as cold:
            first = robot_scene(session=session, scenes=ctx.scenes, robot_id=rid)
        with ctx.sessions() as session, count_statements(ctx.engine) as warm:
            again = robot_scene(session=session, scenes=ctx.scenes, robot_id=rid)
        assert (first.version, first.scene.hash) == (1, scene_hash)
        assert [o.id for o in first.scene.objects] == ["table"]
        assert again.scene is first.scene
        assert (len(cold), len(warm)) == (2, 1)
        with ctx.sessions() as session, pytest.raises(NotFoundError, match="'ghost'"):
            robot_scene(session=session, scenes=ctx.scenes, robot_id="ghost")


def test_a_replica_answers_with_what_another_stored_just_before(database_url: str) -> None:
    with context(database_url) as a, context(database_url) as b:
        model = two_joint(a)
        robot(a, model)
        assert ask(b, [0.0, 0.0], [1.0, 0.0]).source is None  # b has loaded the empty index
        stored = store(a, model, ARM_PATH)
        answer = ask(b, [0.01, 0.0], [0.99, 0.0])
        assert answer.source is PlanSource.CACHE and answer.trajectory_id == stored
