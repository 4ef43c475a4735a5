"""Repair of a near-miss candidate on a real service context (SQLite): the certified parts of
the best rejected path are kept, only its failing stretch is planned, and the joined path is
validated, stored with its parent and answered as "repaired"; otherwise the full planner runs.

The cached path swings the two-joint arm's shoulder 0 → 0.3 → 0.7 → 1 rad, the elbow at 0.2
in between. A small box in the forearm's sweep at shoulder 0.5 blocks only the middle segment;
the worker's own planner, run in this process (`WorkerPlanner`), finds a way past it.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sqlalchemy as sa

from tests.services.hit_setup import context, store, two_joint
from tests.services.plan.test_flow import FakePlanner, WorkerPlanner, use_planner
from tests.waiting import NEVER_BINDS_S
from trajcache.db.end_poses import TrajectoryEndPose
from trajcache.db.models import PlanEvent, Trajectory
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.validation.validator import TrajectoryValidator
from trajcache.planning.problem import PlannerStatus, PlanResult
from trajcache.services.catalog.robots import put_robot
from trajcache.services.catalog.scene_writes import put_scene
from trajcache.services.context import ServiceContext
from trajcache.services.plan import repair
from trajcache.services.plan.flow import PlanAnswer, PlanRequest, PlanSource, plan

PATH = [[0.0, 0.0], [0.3, 0.2], [0.7, 0.2], [1.0, 0.0]]
# Budgets that never bind, even on a loaded machine (the stretch is planned in milliseconds), and
# apart, so that the stretch's problem shows which one it was given.
REPAIR_BUDGET_S = NEVER_BINDS_S / 2


def forearm_box(shoulder: float = 0.5, elbow: float = 0.2, along: float = 0.18) -> dict[str, Any]:
    """A 1 cm box on the forearm's axis, `along` m from the elbow, at these joint angles."""
    ex, ez = 0.3 * math.sin(shoulder), 0.1 + 0.3 * math.cos(shoulder)
    x = ex + along * math.sin(shoulder + elbow)
    z = ez + along * math.cos(shoulder + elbow)
    return {"id": "box", "type": "box", "size": [0.01] * 3, "pose": {"position": [x, 0.0, z]}}


@pytest.fixture
def ctx(tmp_path: Path) -> Iterator[ServiceContext]:
    url = f"sqlite:///{tmp_path / 'repair.db'}"
    with context(url, certificate_audit=True, repair_budget_s=REPAIR_BUDGET_S) as service:
        yield service


def cached(ctx: ServiceContext, objects: list[dict[str, Any]], path: list[list[float]]) -> int:
    model = two_joint(ctx)
    with ctx.sessions() as session:
        put_robot(session=session, robot_id="r1", model_id=model.model_id)
        put_scene(
            session=session, scenes=ctx.scenes, robot_id="r1",
            scene=parse_scene({"objects": objects}),
        )  # fmt: skip
    return store(ctx, model, path)


def ask(ctx: ServiceContext) -> PlanAnswer:
    request = PlanRequest(
        start=np.array([0.02, 0.0]),
        goal=np.array([0.98, 0.0]),
        threshold=0.2,
        max_candidates=3,
        fallback=True,
        budget_s=NEVER_BINDS_S,
    )
    return plan(ctx=ctx, robot_id="r1", request=request)


def solved(path: list[list[float]]) -> PlanResult:
    return PlanResult(PlannerStatus.SOLVED, path=np.array(path), seed=3)


def test_the_failing_stretch_is_planned_and_the_rest_kept(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    parent = cached(ctx, [forearm_box()], PATH)
    planner = WorkerPlanner()
    use_planner(ctx, monkeypatch, planner)
    answer = ask(ctx)
    assert answer.source is PlanSource.REPAIRED and answer.states is not None
    (problem,) = planner.problems  # the stretch only, on the repair budget
    assert (list(problem.start), list(problem.goal)) == ([0.3, 0.2], [0.7, 0.2])
    assert problem.budget_s == pytest.approx(ctx.settings.repair_budget_s)
    states = answer.states.tolist()
    assert states[:2] == [[0.02, 0.0], [0.3, 0.2]] and states[-2:] == [[0.7, 0.2], [0.98, 0.0]]
    assert len(states) > 4
    scene = parse_scene({"objects": [forearm_box()]})
    assert TrajectoryValidator(two_joint(ctx), scene).validate(answer.states).valid
    assert ctx.records.flush(timeout=10)
    with ctx.sessions() as session:
        row = session.get(Trajectory, answer.trajectory_id)
        assert row is not None and row.parent_id == parent
        sources = session.scalars(sa.select(PlanEvent.source)).all()
        ends = session.scalars(
            sa.select(TrajectoryEndPose.end).where(
                TrajectoryEndPose.trajectory_id == answer.trajectory_id
            )
        ).all()
    assert sources == ["repaired"]
    assert sorted(ends) == [0, 1]  # its end poses are indexed


def test_a_repair_that_does_not_certify_falls_back_to_planning(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The planner's stretch goes straight through the box: the service's own validation of
    the new segments rejects it, and the full problem is planned."""
    cached(ctx, [forearm_box()], PATH)
    planner = FakePlanner(solved([[0.3, 0.2], [0.7, 0.2]]))
    use_planner(ctx, monkeypatch, planner)
    answer = ask(ctx)
    assert len(planner.problems) == 2
    assert list(planner.problems[1].start) == [0.02, 0.0]  # the whole request
    assert answer.source is None  # the full planner's path failed validation too


def test_a_stretch_longer_than_half_the_path_is_planned_in_full(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Boxes in the first and last segments: the repair would keep less than half."""
    blocks = [forearm_box(0.15, 0.1, 0.19), {**forearm_box(0.85, 0.1, 0.19), "id": "box2"}]
    cached(ctx, blocks, PATH)
    planner = FakePlanner(PlanResult(PlannerStatus.TIMEOUT, message="no path", seed=1))
    use_planner(ctx, monkeypatch, planner)
    ask(ctx)
    assert [list(p.start) for p in planner.problems] == [[0.02, 0.0]]


def test_repair_is_off_with_a_zero_budget(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with context(f"sqlite:///{tmp_path / 'off.db'}", repair_budget_s=0.0) as ctx:
        cached(ctx, [forearm_box()], PATH)
        planner = WorkerPlanner()
        use_planner(ctx, monkeypatch, planner)
        answer = ask(ctx)
        assert [list(p.start) for p in planner.problems] == [[0.02, 0.0]]
        assert answer.source is not PlanSource.REPAIRED


def test_the_kept_parts_are_validated_too(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Validation stops at a colliding sample without looking at earlier segments, so the parts
    a repair keeps are not proved by the candidate's rejection. Here the stretch chosen is the
    middle segment while the box blocks the first: the joined path must be refused, and the
    full problem planned."""
    cached(ctx, [forearm_box(0.15, 0.1, 0.19)], PATH)
    monkeypatch.setattr(repair, "_failing_stretch", lambda attempt, path: (1, 2))
    planner = WorkerPlanner()
    use_planner(ctx, monkeypatch, planner)
    answer = ask(ctx)
    assert [list(p.start) for p in planner.problems] == [[0.3, 0.2], [0.02, 0.0]]
    assert answer.source is not PlanSource.REPAIRED
