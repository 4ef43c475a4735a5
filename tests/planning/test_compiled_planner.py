"""The compiled planner's sphere covers, its three-valued state check and its search."""

from __future__ import annotations

import itertools
from collections import defaultdict
from functools import cache

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from tests.robots import TWO_JOINT_URDF
from tests.waiting import NEVER_BINDS_S
from trajcache.geometry.collision.checker import FREE, CollisionChecker
from trajcache.geometry.collision.compiled.spheres import COLLIDING, OPEN, sphere_state
from trajcache.geometry.collision.sphere_tables import planner_trees, sphere_tables
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.geometry.validation.validator import TrajectoryValidator
from trajcache.planning.compiled.search import FREE as TREES_FREE
from trajcache.planning.compiled.search import distance, motion, sample_count, seed, simplify
from trajcache.planning.compiled_planner import _Search, plan_compiled
from trajcache.planning.options import SearchOptions
from trajcache.planning.problem import PlannerStatus, PlanResult
from trajcache.planning.query import prepare_query
from trajcache.reference.example_robots import ROBOTS


@cache
def _robot(name: str) -> RobotModel:
    example = ROBOTS[name]
    return load_robot_model(example.urdf, files=example.files(), joint_names=example.joint_names,
                            srdf=example.srdf, group=example.group, base=example.base)  # fmt: skip


def _points(shape: Shape, rng: np.random.Generator, count: int) -> np.ndarray:
    """Points of the shape: on its surface, and inside its solid where it has one."""
    if shape.kind is ShapeKind.MESH:
        assert shape.vertices is not None and shape.faces is not None
        mesh = trimesh.Trimesh(shape.vertices, shape.faces, process=False)
        surface, _ = trimesh.sample.sample_surface(mesh, count, seed=int(rng.integers(1 << 30)))
        return np.asarray(surface)
    half = shape.half_extents()
    box = rng.uniform(-half, half, size=(count * 4, 3))
    if shape.kind is ShapeKind.BOX:
        return box
    radius = shape.size[0]
    if shape.kind is ShapeKind.SPHERE:
        return box[np.linalg.norm(box, axis=1) <= radius]
    if shape.kind is ShapeKind.CYLINDER:
        return box[np.hypot(box[:, 0], box[:, 1]) <= radius]
    seg = np.clip(box[:, 2], -shape.size[1] / 2, shape.size[1] / 2)
    return box[np.linalg.norm(box - np.c_[0 * seg, 0 * seg, seg], axis=1) <= radius]


def _found(tree: tuple[np.ndarray, ...], root: int, point: np.ndarray) -> bool:
    """Whether descending from `root` through the balls that hold `point` reaches a leaf."""
    centre, radius, first, count = tree[2], tree[3], tree[4], tree[5]
    todo = [root]
    while todo:
        k = todo.pop()
        if np.linalg.norm(centre[k] - point) > radius[k]:
            continue
        if first[k] < 0:
            return True
        todo.extend(range(first[k], first[k] + count[k]))
    return False


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_the_sphere_trees_cover_every_link(name: str) -> None:
    """Random surface (and solid) points of every collision element of every example robot are
    found down its sphere tree: inside a leaf ball and inside every ball above it."""
    model = _robot(name)
    checker = CollisionChecker(model, make_scene([]))
    tree = planner_trees(checker.robot)
    rng = np.random.default_rng(3)
    for e, element in enumerate(model.elements):
        points = _points(element.shape, rng, 150)
        placed = points @ element.origin[:3, :3].T + element.origin[:3, 3]  # link frame
        missed = [p for p in placed if not _found(tree, int(tree[1][e]), p)]
        assert not missed, f"{name}: element {e} misses {len(missed)} points"


def _box(oid: str, size: tuple[float, float, float], at: tuple[float, float, float]) -> SceneObject:
    pose = np.eye(4)
    pose[:3, 3] = at
    return SceneObject(oid, Shape(ShapeKind.BOX, size), pose)


def _shelf() -> Scene:
    return make_scene(
        [
            _box("table", (0.8, 1.2, 0.05), (0.55, 0.0, 0.3)),
            _box("wall", (0.05, 1.2, 0.8), (0.85, 0.0, 0.7)),
            _box("board", (0.5, 1.2, 0.03), (0.6, 0.0, 0.75)),
        ]
    )


def _mixed() -> Scene:
    """Round and tilted objects near the arm: their boxes' bounding balls and their boxes
    differ most, where the state check tests the ball first."""
    tilted = np.eye(4)
    tilted[:3, :3] = Rotation.from_euler("xyz", [0.4, -0.3, 0.7]).as_matrix()
    tilted[:3, 3] = (0.45, 0.15, 0.45)
    post, ball = np.eye(4), np.eye(4)
    post[:3, 3], ball[:3, 3] = (0.35, -0.25, 0.5), (0.2, 0.35, 0.7)
    return make_scene(
        [
            SceneObject("tilted", Shape(ShapeKind.BOX, (0.3, 0.04, 0.2)), tilted),
            SceneObject("post", Shape(ShapeKind.CYLINDER, (0.04, 0.5)), post),
            SceneObject("ball", Shape(ShapeKind.SPHERE, (0.09,)), ball),
        ]
    )


@pytest.mark.parametrize("scene", ["shelf", "mixed"])
@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_the_state_check_proves_only_what_the_exact_check_finds(name: str, scene: str) -> None:
    """FREE only where FCL finds no contact, COLLIDING only where it finds one; and the covers
    settle most states (else the planner would hand everything to the exact check)."""
    model = _robot(name)
    checker = CollisionChecker(model, _shelf() if scene == "shelf" else _mixed())
    tables = sphere_tables(checker)
    work = tables.work()
    rng = np.random.default_rng(11)
    states = model.lower + rng.random((600, model.dof)) * (model.upper - model.lower)
    got = np.array([sphere_state(q, tables.fk, tables.robot, tables.scene, tables.pairs, work)
                    for q in states])  # fmt: skip
    exact = checker.check(states, stop_at_first=False).status
    assert not np.any((got == 0) & (exact != FREE))
    assert not np.any((got == COLLIDING) & (exact == FREE))
    assert np.any(got == COLLIDING) and np.any(got == 0) and np.any(got == OPEN)


def test_the_compiled_planner_finds_a_certified_path_around_a_wall() -> None:
    model = load_robot_model(TWO_JOINT_URDF)
    scene = make_scene([_box("lid", (0.15, 0.3, 0.06), (0.05, 0.0, 0.57))])
    start, goal = np.array([-1.2, 0.3]), np.array([1.2, 0.3])
    direct = CollisionChecker(model, scene).check(np.linspace(start, goal, 40), stop_at_first=True)
    assert direct.first_collision >= 0  # the straight way is blocked
    result = plan_compiled(
        model,
        scene,
        start,
        goal,
        options=SearchOptions(budget_s=NEVER_BINDS_S, seed=1, shortcut_s=0.0),
    )
    assert result.status is PlannerStatus.SOLVED, result.message
    assert result.path is not None
    np.testing.assert_allclose(result.path[0], start)
    np.testing.assert_allclose(result.path[-1], goal)
    assert TrajectoryValidator(model, scene).validate(result.path).valid
    assert result.stats["search_ms"] > 0.0


def test_the_worker_task_dispatches_compiled_for_a_planar_base() -> None:
    """By name through the worker task, for the reference robot on its planar base (held still
    here), in the restroom: a certified path."""
    from dataclasses import replace

    from tests.planning.test_ompl_planner import DOWN, FORWARD
    from trajcache.geometry.scene.payload import scene_to_payload
    from trajcache.planning.problem import ModelSource, PlanningProblem, SceneSource
    from trajcache.planning.run import run_planning
    from trajcache.reference.restroom import restroom_layout, restroom_scene
    from trajcache.reference.robot import reference_model, reference_urdf

    model = reference_model()
    scene = restroom_scene(doors=45.0)
    station = restroom_layout().station("stall_2")
    base = (station.x, station.y, station.theta)
    source = ModelSource(model_id=model.model_id, urdf=reference_urdf(), base=model.base.value,
                         joint_names=model.joint_names)  # fmt: skip
    payload = SceneSource(scene.hash, scene_to_payload(scene))
    problem = PlanningProblem(model=source, scene=payload, start=base + DOWN, goal=base + FORWARD,
                              budget_s=NEVER_BINDS_S, seed=3)  # fmt: skip
    result = run_planning(replace(problem, planner="compiled"))
    assert result.status is PlannerStatus.SOLVED, result.message
    assert result.path is not None
    assert TrajectoryValidator(model, scene).validate(result.path).valid
    assert "search_ms" in result.stats


def test_oriented_boxes_said_apart_are_apart_and_overlapping_ones_are_not() -> None:
    """`obb_apart` against FCL's box distance on random pairs: every pair it calls apart is
    apart, and it calls apart nearly every pair that FCL finds more than 1 mm apart."""
    import fcl
    from scipy.spatial.transform import Rotation

    from trajcache.geometry.collision.compiled.spheres import obb_apart

    rng = np.random.default_rng(7)
    count = 400
    rot = Rotation.random(2 * count, random_state=3).as_matrix().reshape(2, count, 3, 3)
    centre = rng.uniform(-0.3, 0.3, size=(2, count, 3))
    half = rng.uniform(0.01, 0.2, size=(2, count, 3))
    said, missed = 0, 0
    for k in range(count):
        boxes = [
            fcl.CollisionObject(fcl.Box(*(2 * half[s, k])), fcl.Transform(rot[s, k], centre[s, k]))
            for s in range(2)
        ]
        gap = fcl.distance(boxes[0], boxes[1], fcl.DistanceRequest(), fcl.DistanceResult())
        apart = obb_apart(rot[0], k, centre[0], half[0], rot[1], k, centre[1], half[1])
        if apart:
            said += 1
            assert gap > 0.0, (k, gap)
        elif gap > 1e-3:
            missed += 1
    assert said > count // 4
    assert missed == 0  # the separating axis theorem is exact for boxes


def test_pending_motions_are_decided_as_each_ones_exact_check_decides_it() -> None:
    """`_resolve` checks the open states of all pending motions in two batches; each motion's
    verdict is the one its own exact check gives: free when none of its open states collides."""
    from trajcache.planning.compiled.search import motion, sample_count
    from trajcache.planning.compiled_planner import PENDING, _Search
    from trajcache.planning.query import prepare_query

    model = _robot("panda")
    scene = _shelf()
    rng = np.random.default_rng(5)
    states = model.lower + rng.random((200, model.dof)) * (model.upper - model.lower)
    free = states[CollisionChecker(model, scene).check(states, stop_at_first=False).status == FREE]
    query = prepare_query(model, scene, free[0], free[1])
    assert not isinstance(query, PlanResult)
    search = _Search(query, sphere_tables(query.checker.checker), defaultdict(float))
    nodes = np.zeros((2, 2 * PENDING, model.dof))
    chosen: list[tuple[np.ndarray, np.ndarray]] = []
    while len(chosen) < PENDING:
        a = model.lower + rng.random(model.dof) * (model.upper - model.lower)
        b = np.clip(a + rng.uniform(-0.4, 0.4, model.dof), model.lower, model.upper)
        out = np.empty((sample_count(a, b, search.space), model.dof))
        if motion(a, b, *search._args(), out)[0] == OPEN:  # type: ignore[call-arg]
            chosen.append((a, b))
    for k, (a, _) in enumerate(chosen):
        nodes[0, k] = a
    pending = (
        np.zeros(PENDING, dtype=np.int64),
        np.arange(PENDING, dtype=np.int64),
        np.array([b for _, b in chosen]),
        np.full(PENDING, -1, dtype=np.int64),
        np.zeros(PENDING, dtype=np.int8),
        np.array([PENDING], dtype=np.int64),
    )
    search._resolve((nodes, None, None), pending)  # type: ignore[arg-type]
    alone = [search.motion_free(a, b) for a, b in chosen]
    assert [bool(v) for v in pending[4]] == alone
    assert any(alone) and not all(alone)


def test_simplification_keeps_the_ends_shortens_and_takes_only_free_motions() -> None:
    """A random walk of motions the trees prove free, simplified: the same ends, a path at
    most as long (and here much shorter), every motion of it FREE by the trees."""
    model = load_robot_model(TWO_JOINT_URDF)
    scene = make_scene([_box("lid", (0.15, 0.3, 0.06), (0.05, 0.0, 0.57))])
    query = prepare_query(model, scene, [-1.2, 0.3], [1.2, 0.3])
    assert not isinstance(query, PlanResult)
    search = _Search(query, sphere_tables(query.checker.checker), defaultdict(float))  # type: ignore[arg-type]
    rng = np.random.default_rng(3)
    seed(3)
    lower, upper = model.lower, model.upper
    shortened = 0
    for _ in range(10):
        walk = [np.array([-1.2, 0.3])]
        while len(walk) < 12:
            step = np.clip(walk[-1] + rng.normal(0.0, 0.5, 2), lower, upper)
            if search._open_states(walk[-1], step)[0] == TREES_FREE:
                walk.append(step)
        path = np.zeros((40, 2))
        path[: len(walk)] = walk
        before = sum(distance(a, b, False) for a, b in itertools.pairwise(walk))
        count = simplify(path, len(walk), *search._args(), 24)  # type: ignore[call-arg]
        out = path[:count]
        np.testing.assert_array_equal(out[0], walk[0])
        np.testing.assert_array_equal(out[-1], walk[-1])
        after = sum(distance(a, b, False) for a, b in itertools.pairwise(out))
        assert after <= before + 1e-9
        shortened += after < 0.8 * before
        for a, b in itertools.pairwise(out):
            buffer = np.empty((sample_count(a, b, search.space), 2))
            assert motion(a, b, *search._args(), buffer)[0] == TREES_FREE  # type: ignore[call-arg]
    assert shortened >= 8
