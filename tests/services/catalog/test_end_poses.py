"""The end-pose index on SQLite and PostgreSQL: written by every store path (store, import,
planner and seed answers, the backlog of older rows), deleted with its trajectory, and read by
pose lookups that see every trajectory, through a tip's rigidly attached links too."""

from __future__ import annotations

import json
from collections.abc import Iterator

import numpy as np
import pytest
import sqlalchemy as sa

from tests.robots import PINCER_SRDF, Y_AXIS, box, collision, cylinder, joint, link, robot
from tests.services.maintenance.test_bulk_import import many
from tests.services.maintenance.test_transfer import run_import
from tests.services.plan.test_flow import FakePlanner, use_planner
from trajcache.core.config import Settings
from trajcache.db.end_poses import EndPoseBacklog, TrajectoryEndPose
from trajcache.db.models import TrajectoryCommit
from trajcache.geometry.model.end_poses import anchor_of, indexed_anchors
from trajcache.geometry.model.ik import PoseTarget
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.parse import parse_scene
from trajcache.planning.problem import PlannerStatus, PlanResult
from trajcache.services.catalog.models import ModelRegistration, register_model
from trajcache.services.catalog.trajectories import (
    NewTrajectory,
    delete_trajectory,
    store_trajectory,
)
from trajcache.services.context import ServiceContext
from trajcache.services.ik.cached import ends_within, nearest_starts, pose_ends
from trajcache.services.maintenance.backfill import index_backlog_batch
from trajcache.services.maintenance.eviction import prune
from trajcache.services.plan.attempt import PlanRequest
from trajcache.services.plan.flow import plan_in_scene

# The two-joint arm with a tool fixed 0.2 m beyond the forearm: the tool is the end-effector
# link (the deepest), anchored on the forearm.
TOOLED_URDF = robot(
    "tooled",
    link("base", collision(box(0.2, 0.2, 0.1), xyz=(0, 0, 0.05))),
    link("upper", collision(cylinder(0.03, 0.3), xyz=(0, 0, 0.15))),
    link("fore", collision(cylinder(0.02, 0.2), xyz=(0, 0, 0.1))),
    link("tool"),
    joint("shoulder", "revolute", "base", "upper", xyz=(0, 0, 0.1), axis=Y_AXIS, limit=(-2, 2)),
    joint("elbow", "revolute", "upper", "fore", xyz=(0, 0, 0.3), axis=Y_AXIS, limit=(-1.5, 1.5)),
    joint("tool_mount", "fixed", "fore", "tool", xyz=(0, 0, 0.2)),
)


@pytest.fixture
def ctx(migrated_url: str) -> Iterator[ServiceContext]:
    context = ServiceContext.create(Settings(database_url=migrated_url, worker_backend="none"))
    yield context
    context.close()


@pytest.fixture
def tooled(ctx: ServiceContext) -> RobotModel:
    with ctx.sessions() as session:
        model, _ = register_model(
            session=session, registry=ctx.models, registration=ModelRegistration(urdf=TOOLED_URDF)
        )
    return model


def store(ctx: ServiceContext, model: RobotModel, *states: list[float], commit: bool = True) -> int:
    with ctx.sessions() as session:
        new_id, _ = store_trajectory(
            session=session, trajectory=NewTrajectory(model, list(states), "sim"),
            settings=Settings(), compute_quality=False, commit=commit,
        )  # fmt: skip
        if not commit:
            session.rollback()
    return new_id


def rows_of(ctx: ServiceContext, trajectory_id: int | None = None) -> list[TrajectoryEndPose]:
    E = TrajectoryEndPose
    query = sa.select(E).order_by(E.trajectory_id, E.end, E.link)
    if trajectory_id is not None:
        query = query.where(E.trajectory_id == trajectory_id)
    with ctx.sessions() as session:
        found = list(session.scalars(query))
        session.expunge_all()
    return found


def tool_target(model: RobotModel, state: list[float], tolerance: float = 1e-3) -> PoseTarget:
    pose = link_transforms(model, np.array(state))[0, model.link_names.index("tool")]
    return PoseTarget("tool", pose, tolerance, 1e-2)


def test_tips_are_indexed_by_the_link_they_are_fixed_on() -> None:
    model = load_robot_model(TOOLED_URDF)
    names = model.link_names
    assert names[anchor_of(model, names.index("tool"))] == "fore"
    assert names[anchor_of(model, names.index("base"))] == "base"
    assert indexed_anchors(model, None) == ("fore",)
    srdf = PINCER_SRDF.replace(
        "</robot>",
        '<group name="reach"><chain base_link="base" tip_link="upper"/></group>'
        '<end_effector name="hand" parent_link="tool" group="arm"/></robot>',
    )
    assert indexed_anchors(model, srdf) == ("fore", "upper")


def test_a_stored_trajectory_gets_the_poses_of_its_ends(
    ctx: ServiceContext, tooled: RobotModel
) -> None:
    start, goal = [0.1, 0.2], [0.9, -0.4]
    trajectory_id = store(ctx, tooled, start, [0.5, 0.0], goal)
    rows = rows_of(ctx, trajectory_id)
    assert [(r.end, r.link, r.model_id) for r in rows] == [
        (0, "fore", tooled.model_id),
        (1, "fore", tooled.model_id),
    ]
    fore = tooled.link_names.index("fore")
    for row, state in zip(rows, (start, goal), strict=True):
        pose = link_transforms(tooled, np.array(state))[0, fore]
        np.testing.assert_allclose([row.x, row.y, row.z], pose[:3, 3], atol=1e-12)
    with ctx.sessions() as session:
        logged = session.scalar(sa.select(sa.func.count()).select_from(TrajectoryCommit))
    assert store(ctx, tooled, start, [0.5, 0.0], goal) == trajectory_id  # stored once
    assert len(rows_of(ctx)) == 2
    with ctx.sessions() as session:  # and no second commit-log row
        assert session.scalar(sa.select(sa.func.count()).select_from(TrajectoryCommit)) == logged
    unstored = store(ctx, tooled, [0.0, 0.0], [0.3, 0.3], commit=False)  # rolled back
    assert rows_of(ctx, unstored) == []


def test_a_trajectory_older_than_any_pool_is_found_by_its_tool_pose(
    ctx: ServiceContext, tooled: RobotModel
) -> None:
    """The first of 300 trajectories ends where the tool is asked for: the index sees it
    (the last 256 were all the lookup saw before), through the forearm's rows and the tool's
    fixed offset; a pose 5 mm off is outside a 1 mm tolerance."""
    oldest = store(ctx, tooled, [0.0, 0.0], [1.2, -0.7])
    rng = np.random.default_rng(3)
    with ctx.sessions() as session:
        for goal in rng.uniform([-1.0, -1.4], [-0.2, 1.4], (299, 2)):
            trajectory = NewTrajectory(tooled, [[0.0, 0.0], goal.tolist()], "sim")
            store_trajectory(
                session=session, trajectory=trajectory,
                settings=Settings(), compute_quality=False, commit=False,
            )  # fmt: skip
        session.commit()
        target = tool_target(tooled, [1.2, -0.7])
        base = np.zeros(2)
        found = ends_within(session, tooled, tooled, target, base)
        np.testing.assert_allclose(found.states, [[1.2, -0.7]])
        np.testing.assert_allclose(found.partners, [[0.0, 0.0]])
        for stored in (300, 10**6):  # the shortlist of one scan, or of a search by radii
            both = pose_ends(session, tooled, tooled, target, base, stored=stored)
            np.testing.assert_allclose(both.within.states, [[1.2, -0.7]])
        target.pose[0, 3] += 0.005
        goal = target.pose[:3, 3]
        assert len(ends_within(session, tooled, tooled, target, base).gaps) == 0
        starts = nearest_starts(session, tooled, tooled, target, base, stored=300)
        widening = nearest_starts(session, tooled, tooled, target, base, stored=10**6)
        np.testing.assert_allclose(widening, starts)  # searched in widening radii
        for stored in (300, 10**6):  # one read of the index, or each search by its own
            both = pose_ends(session, tooled, tooled, target, base, stored=stored)
            np.testing.assert_allclose(both.starts, starts)
            assert len(both.within.gaps) == 0
    np.testing.assert_allclose(starts[0], [1.2, -0.7])  # the nearest start, the others beyond
    tool = tooled.link_names.index("tool")  # ranked by the tool's own distance from its target
    gaps = [np.linalg.norm(link_transforms(tooled, s)[0, tool, :3, 3] - goal) for s in starts]
    assert gaps == sorted(gaps) and len(starts) == 3
    assert oldest == min(r.trajectory_id for r in rows_of(ctx))


def test_a_pose_goal_reads_every_end_within_its_tolerances_in_one_read_or_two(
    ctx: ServiceContext, tooled: RobotModel
) -> None:
    """`pose_ends` reads the IK starts' shortlist once and takes the ends within the tolerances
    from it, unless all of the shortlist is within them: then it searches for them all. 20 ends
    put the tool within 1 mm of the target (more than the shortlist holds), 5 elsewhere."""
    goal = np.array([1.2, -0.7])
    rng = np.random.default_rng(5)
    for k in range(20):
        store(ctx, tooled, [0.0, 0.07 * k], (goal + rng.uniform(-2e-4, 2e-4, 2)).tolist())
    for k in range(5):
        store(ctx, tooled, [0.0, 0.0], [0.2 * k - 1.0, 0.5])
    target = tool_target(tooled, goal.tolist())
    base = np.zeros(2)
    with ctx.sessions() as session:
        within = ends_within(session, tooled, tooled, target, base)
        assert len(within.gaps) == 20
        for stored in (25, 10**6):  # one scan, or a search by radii: the shortlist is full
            found = pose_ends(session, tooled, tooled, target, base, stored=stored)
            np.testing.assert_allclose(found.within.states, within.states)
            np.testing.assert_allclose(found.within.partners, within.partners)
        starts = nearest_starts(session, tooled, tooled, target, base, stored=25)
        np.testing.assert_allclose(found.starts, starts)
        target.pose[2, 3] += 0.05  # 5 cm off: none within, the starts as before
        off = pose_ends(session, tooled, tooled, target, base, stored=25)
        assert len(off.within.gaps) == 0
        np.testing.assert_allclose(
            off.starts, nearest_starts(session, tooled, tooled, target, base, stored=25)
        )


def test_deletes_and_evictions_take_the_rows_with_them(
    ctx: ServiceContext, tooled: RobotModel
) -> None:
    ids = [store(ctx, tooled, [0.0, 0.0], [0.1 * k, 0.2]) for k in range(1, 5)]
    with ctx.sessions() as session:
        delete_trajectory(session=session, trajectory_id=ids[0])
        report = prune(session=session, cap=1, policy="lru", dry_run=False)
    assert report.deleted == 2
    survivor = ({*ids} - {ids[0], *report.models[0].ids}).pop()
    assert {r.trajectory_id for r in rows_of(ctx)} == {survivor}


def test_imported_trajectories_get_theirs_in_the_import(ctx: ServiceContext) -> None:
    lines = many(5)
    report = run_import(ctx, lines)
    assert report.inserted == 5
    rows = rows_of(ctx)
    assert len(rows) == 10 and len({r.trajectory_id for r in rows}) == 5
    again = run_import(ctx, lines)  # duplicates write nothing
    assert (again.inserted, len(rows_of(ctx))) == (0, 10)
    model_line = json.loads(lines[1])
    assert {r.link for r in rows} == set(
        indexed_anchors(load_robot_model(model_line["urdf"]), model_line.get("srdf"))
    )


def test_trajectories_of_the_backlog_get_theirs_in_the_background(
    ctx: ServiceContext, tooled: RobotModel
) -> None:
    """A row stored before the index existed (its backlog entry, as migration 0016 writes)."""
    ids = [store(ctx, tooled, [0.0, 0.0], [0.1 * k, 0.2]) for k in range(1, 4)]
    with ctx.sessions() as session:
        session.execute(
            sa.delete(TrajectoryEndPose).where(TrajectoryEndPose.trajectory_id != ids[2])
        )
        session.execute(sa.insert(EndPoseBacklog), [{"trajectory_id": i} for i in ids])
        session.commit()
    assert index_backlog_batch(ctx, 2) == 2
    assert index_backlog_batch(ctx, 2) == 1  # ids[2]'s rows are written again, not twice
    assert index_backlog_batch(ctx, 2) == 0
    assert sorted(r.trajectory_id for r in rows_of(ctx)) == sorted(ids * 2)
    with ctx.sessions() as session:
        assert session.scalar(sa.select(sa.func.count()).select_from(EndPoseBacklog)) == 0


def test_a_seed_jobs_planned_answer_is_indexed(
    ctx: ServiceContext, tooled: RobotModel, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What a seed job runs for each query (`plan_in_scene`), stored as `sim`."""
    path = np.array([[0.0, 0.0], [0.4, 0.3], [0.8, 0.1]])
    use_planner(ctx, monkeypatch, FakePlanner(PlanResult(PlannerStatus.SOLVED, path=path, seed=1)))
    request = PlanRequest(start=path[0], goal=path[-1], threshold=0.2, max_candidates=3)
    answer = plan_in_scene(
        ctx=ctx, caller="seed-job-1", model_id=tooled.model_id,
        scene=parse_scene({"objects": []}), request=request,
    )  # fmt: skip
    assert answer.trajectory_id is not None and answer.stored
    assert [r.end for r in rows_of(ctx, answer.trajectory_id)] == [0, 1]
