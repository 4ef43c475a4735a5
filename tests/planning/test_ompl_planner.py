"""OMPL planning with the reference robot in the restroom, and the state-space glue under it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.robots import TWO_ROD_URDF
from tests.waiting import NEVER_BINDS_S
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.geometry.validation.validator import TrajectoryValidator
from trajcache.planning import ompl_planner
from trajcache.planning.motion import MotionChecker, coarse_to_fine
from trajcache.planning.ompl_planner import plan_ompl, planner_names
from trajcache.planning.options import SearchOptions
from trajcache.planning.problem import PlannerStatus, PlanResult
from trajcache.planning.query import Query, prepare_query
from trajcache.planning.space import state_space_spec
from trajcache.reference.restroom import restroom_layout, restroom_scene
from trajcache.reference.robot import STOWED_ARM, reference_model

# Two arm configurations at stall 2 (doors at 45°) whose straight segment collides.
DOWN = (-2.39, 1.55, 0.96, 1.02, 1.75, -0.29, 2.48)
FORWARD = (0.27, 0.53, 2.65, 3.46, -2.78, 2.04, -1.5)


@pytest.fixture(scope="module")
def model() -> RobotModel:
    return reference_model()


@pytest.fixture(scope="module")
def scene() -> Scene:
    return restroom_scene(doors=45.0)


def station(name: str) -> list[float]:
    s = restroom_layout().station(name)
    return [s.x, s.y, s.theta]


def arm_query() -> tuple[np.ndarray, np.ndarray]:
    base = station("stall_2")
    return np.array(base + list(DOWN)), np.array(base + list(FORWARD))


def assert_certified(model: RobotModel, scene: Scene, result: PlanResult) -> None:
    assert result.status is PlannerStatus.SOLVED, result.message
    assert result.path is not None and result.solved
    assert TrajectoryValidator(model, scene).validate(result.path).valid


def test_arm_motion_around_an_obstacle_is_certified(model: RobotModel, scene: Scene) -> None:
    start, goal = arm_query()
    query = prepare_query(model, scene, start, goal)
    assert isinstance(query, Query) and query.base_still
    assert not query.checker.segment_free(start, goal)  # the straight motion collides
    result = plan_ompl(
        model, scene, start, goal, options=SearchOptions(budget_s=NEVER_BINDS_S, seed=1)
    )
    assert_certified(model, scene, result)
    assert result.path is not None and len(result.path) >= 3
    assert np.allclose(result.path[0], start) and np.allclose(result.path[-1], goal)
    assert np.allclose(result.path[:, :3], start[:3])  # the base stayed at the station
    stats = result.stats
    assert stats["length_after"] <= stats["length_before"] + 1e-9
    assert stats["checks"] > 0 and stats["plan_ms"] > 0


def test_base_drives_around_a_pillar(model: RobotModel) -> None:
    room = restroom_scene(doors=0.0)
    pillar = np.eye(4)
    pillar[:3, 3] = (1.825, 1.3, 1.0)
    box = Shape(ShapeKind.BOX, (0.3, 0.3, 2.0))
    scene = make_scene([*room.objects, SceneObject("pillar", box, pillar)], room.env)
    start = np.array(station("stall_2") + list(STOWED_ARM))
    goal = np.array(station("stall_3") + list(STOWED_ARM))
    query = prepare_query(model, scene, start, goal)
    assert isinstance(query, Query) and not query.base_still
    assert not query.checker.segment_free(start, goal)
    result = plan_ompl(
        model, scene, start, goal, options=SearchOptions(budget_s=NEVER_BINDS_S, seed=3)
    )
    assert_certified(model, scene, result)
    assert result.path is not None
    assert np.abs(result.path[:, 1] - 1.3).max() > 0.2  # it left the straight line


def test_fixed_base_arm_folds_past_a_post() -> None:
    model = load_robot_model(TWO_ROD_URDF, base="fixed")
    post = np.eye(4)
    post[:3, 3] = (0.75, 0.0, 0.5)  # on the line the stretched arm sweeps through
    scene = make_scene([SceneObject("post", Shape(ShapeKind.BOX, (0.1, 0.1, 1.0)), post)])
    start, goal = np.array([-1.0, 0.0]), np.array([1.0, 0.0])
    query = prepare_query(model, scene, start, goal)
    assert isinstance(query, Query) and not query.checker.segment_free(start, goal)
    result = plan_ompl(
        model, scene, start, goal, options=SearchOptions(budget_s=NEVER_BINDS_S, seed=0)
    )
    assert_certified(model, scene, result)
    assert result.path is not None
    assert np.abs(result.path[:, 1]).max() > 0.5  # the elbow folded to pass the post


def test_unknown_planner_is_an_error_naming_the_valid_ones(model: RobotModel, scene: Scene) -> None:
    start, goal = arm_query()
    result = plan_ompl(
        model, scene, start, goal, planner="astar", options=SearchOptions(budget_s=1.0, seed=0)
    )
    assert result.status is PlannerStatus.ERROR and result.path is None
    for name in ("rrtconnect", "rrt", "bitstar", "prm", "kpiece"):
        assert name in result.message
    assert "astar" in result.message


def test_endpoints_in_collision_are_rejected_without_planning(
    model: RobotModel, scene: Scene
) -> None:
    start, goal = arm_query()
    in_wall = start.copy()
    in_wall[:2] = (0.05, 1.0)  # the base overlaps the west wall
    result = plan_ompl(model, scene, in_wall, goal, options=SearchOptions(budget_s=2.0, seed=0))
    assert result.status is PlannerStatus.INVALID_START
    assert "wall_west" in result.message
    result = plan_ompl(model, scene, start, in_wall, options=SearchOptions(budget_s=2.0, seed=0))
    assert result.status is PlannerStatus.INVALID_GOAL
    out_of_limits = goal.copy()
    out_of_limits[4] = 3.0  # joint2 upper limit is 2.0944
    result = plan_ompl(
        model, scene, start, out_of_limits, options=SearchOptions(budget_s=2.0, seed=0)
    )
    assert result.status is PlannerStatus.INVALID_GOAL and "joint2" in result.message


def test_tiny_budget_on_an_impossible_problem_times_out_quickly(
    model: RobotModel, monkeypatch: pytest.MonkeyPatch
) -> None:
    scene = restroom_scene(doors=0.0)  # every stall closed
    start = np.array(station("stall_1") + list(STOWED_ARM))
    inside = np.array([0.45, 2.9, 0.0, *STOWED_ARM])  # in stall 1, behind the closed door
    query = prepare_query(model, scene, start, inside)
    assert isinstance(query, Query), "the goal must be free for this test"
    budget = 0.3
    given: list[float] = []  # the seconds each OMPL solve was allowed
    timed = ompl_planner.ob.timedPlannerTerminationCondition
    monkeypatch.setattr(
        ompl_planner.ob,
        "timedPlannerTerminationCondition",
        lambda seconds: given.append(seconds) or timed(seconds),
    )
    result = plan_ompl(model, scene, start, inside, options=SearchOptions(budget_s=budget, seed=0))
    assert result.status is PlannerStatus.TIMEOUT and result.path is None
    assert given and all(0.0 < seconds <= budget for seconds in given)  # OMPL got the budget


def test_naive_baseline_solves_the_same_query(model: RobotModel, scene: Scene) -> None:
    start, goal = arm_query()
    result = plan_ompl(
        model, scene, start, goal, naive=True, options=SearchOptions(budget_s=NEVER_BINDS_S, seed=1)
    )
    assert_certified(model, scene, result)
    # one call per state, except the endpoint check (start and goal in one call)
    assert result.stats["check_calls"] == result.stats["checks"] - 1


def test_same_seed_gives_the_same_path(model: RobotModel, scene: Scene) -> None:
    start, goal = arm_query()
    # a budget that never binds, even on a loaded machine: a cut-short shortcut phase differs
    first = plan_ompl(
        model, scene, start, goal, options=SearchOptions(budget_s=NEVER_BINDS_S, seed=5)
    )
    second = plan_ompl(
        model, scene, start, goal, options=SearchOptions(budget_s=NEVER_BINDS_S, seed=5)
    )
    assert first.path is not None and second.path is not None
    assert first.path.shape == second.path.shape and np.allclose(first.path, second.path)


@pytest.mark.parametrize("planner", ["rrt", "prm", "kpiece", "bitstar"])
def test_other_planners_run_in_both_kinds_of_space(
    model: RobotModel, scene: Scene, planner: str
) -> None:
    start, goal = arm_query()
    result = plan_ompl(
        model,
        scene,
        start,
        goal,
        planner=planner,
        options=SearchOptions(budget_s=NEVER_BINDS_S, seed=2),
    )
    assert_certified(model, scene, result)
    stowed = list(STOWED_ARM)
    drive_from = np.array(station("stall_3") + stowed)
    drive_to = np.array([3.4, 1.6, -math.pi / 2, *stowed])  # base turns and moves
    result = plan_ompl(
        model,
        scene,
        drive_from,
        drive_to,
        planner=planner,
        options=SearchOptions(budget_s=NEVER_BINDS_S, seed=2),
    )
    assert_certified(model, scene, result)


def test_planner_names_cover_the_aliases() -> None:
    assert {"rrtconnect", "rrt", "bitstar", "bit*", "prm", "kpiece"} <= set(planner_names())


# --- the state-space glue ---------------------------------------------------------------


def test_base_angle_takes_the_short_way(model: RobotModel, scene: Scene) -> None:
    spec = state_space_spec(model, scene)
    a = np.zeros(model.dof)
    b = np.zeros(model.dof)
    a[2], b[2] = 3.1, -3.1
    assert spec.distance(a, b) == pytest.approx(2 * math.pi - 6.2)
    mid = spec.interpolate(a, b, 0.5)
    assert abs(abs(mid[2]) - math.pi) < 1e-9
    assert spec.path_length([a, b]) == pytest.approx(spec.distance(a, b))
    lo, hi = spec.lower[:2], spec.upper[:2]
    assert np.all(lo <= 0.0) and np.all(hi >= (6.0, 4.0))  # the whole room


def test_held_base_never_moves_when_sampling(model: RobotModel, scene: Scene) -> None:
    start, _ = arm_query()
    spec = state_space_spec(model, scene, hold_base=start)
    rng = np.random.default_rng(0)
    for _ in range(20):
        assert np.allclose(spec.sample(rng)[:3], start[:3])
        assert np.allclose(spec.sample_near(start, 1.0, rng)[:3], start[:3])


def test_coarse_to_fine_is_a_permutation_ending_first() -> None:
    for n in (0, 1, 2, 7, 16, 33):
        order = coarse_to_fine(n)
        assert sorted(order.tolist()) == list(range(n))
        if n:
            assert order[0] == n - 1


def test_segment_checks_are_batched_and_counted(model: RobotModel, scene: Scene) -> None:
    start, goal = arm_query()
    spec = state_space_spec(model, scene, hold_base=start)
    checker = MotionChecker(spec, scene)
    samples = len(spec.extend(start, goal))
    assert samples > 10
    assert checker.segment_free(start, goal) is False
    assert checker.calls == 1 and checker.segments_checked == 1
    assert checker.states_checked == samples
    counts = checker.segments_collisions(np.stack([start, start]), np.stack([goal, start]))
    assert counts[0] > 0 and counts[1] == 0
    assert checker.calls == 2
