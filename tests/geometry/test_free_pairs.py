"""Self-collision pairs proven free within the limits, and dropped from every check."""

from __future__ import annotations

import fcl
import numpy as np
import pytest

from tests.robots import planar_arm
from trajcache.geometry.collision.bodies import Posed, RobotGeometry
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.collision.free_pairs import proven_free_pairs
from trajcache.geometry.collision.shared import robot_geometry
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene
from trajcache.reference.robot import reference_model


def _fold(limit: float) -> RobotModel:
    """A planar arm folding in the horizontal plane: l3 can swing back onto l1 unless j2 and j3
    are kept near straight; the pair (l1, l3) moves apart by j2 and j3 only."""
    urdf = planar_arm((1.0, 0.5, 0.8), name="fold", limits=(3, limit, limit), width=0.1)
    return load_robot_model(urdf)


def _links(robot: RobotGeometry, pairs: list[tuple[int, int]]) -> set[tuple[str, str]]:
    names = robot.model.link_names
    link = robot.element_link
    return {(names[link[i]], names[link[j]]) for i, j in pairs}


def _random_states(model: RobotModel, count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    states = np.zeros((count, model.dof))
    arm = slice(model.arm_offset, model.dof)
    states[:, arm] = rng.uniform(model.lower[arm], model.upper[arm], (count, model.dof - arm.start))
    return states


def test_a_pair_that_folds_onto_itself_keeps_being_checked() -> None:
    model = _fold(2.9)
    robot = RobotGeometry(model)
    assert not proven_free_pairs(robot).any()
    folded = np.array([[0.0, 2.8, 2.8]])  # l3 swung back across l1
    assert CollisionChecker(model, Scene(objects=())).check(folded).first_collision == 0


def test_a_pair_kept_apart_by_its_limits_is_dropped() -> None:
    model = _fold(0.5)
    robot = RobotGeometry(model)
    free = proven_free_pairs(robot)
    pairs = list(zip(robot.pair_i.tolist(), robot.pair_j.tolist(), strict=True))
    assert _links(robot, [p for p, f in zip(pairs, free, strict=True) if f]) == {("l1", "l3")}
    shared = robot_geometry(model)
    assert _links(shared, shared.proven_free) == {("l1", "l3")}
    assert len(shared.pair_i) == len(robot.pair_i) - 1


def test_near_the_limit_where_the_pair_starts_touching_only_the_touching_side_is_kept() -> None:
    # l3 first reaches l1 with j2 and j3 near ±1.83 rad: at ±1.85 a few states touch.
    grid = np.linspace(-1.85, 1.85, 200)
    j2, j3 = np.meshgrid(grid, grid)
    states = np.column_stack([np.zeros(j2.size), j2.ravel(), j3.ravel()])
    touching = CollisionChecker(_fold(1.85), Scene(objects=())).check(states, stop_at_first=False)
    assert 0 < (touching.status < 0).sum() < 100
    assert not proven_free_pairs(RobotGeometry(_fold(1.85))).any()
    assert proven_free_pairs(RobotGeometry(_fold(1.8))).any()


@pytest.mark.parametrize("seed", [1, 2])
def test_dropped_pairs_of_the_reference_robot_never_collide_within_the_limits(seed: int) -> None:
    model = reference_model()
    robot = robot_geometry(model)
    assert ("link5", "link7") in _links(robot, robot.proven_free)  # the wrist pair
    posed = Posed.build(robot, _random_states(model, 5_000, seed))
    poses = posed.elements
    request = fcl.DistanceRequest()
    for i, j in robot.proven_free:
        a = fcl.CollisionObject(robot.geometries[i], fcl.Transform())
        b = fcl.CollisionObject(robot.geometries[j], fcl.Transform())
        closest = np.inf
        for pose_a, pose_b in zip(poses[:, i], poses[:, j], strict=True):
            a.setTransform(fcl.Transform(pose_a[:3, :3], pose_a[:3, 3]))
            b.setTransform(fcl.Transform(pose_b[:3, :3], pose_b[:3, 3]))
            closest = min(closest, fcl.distance(a, b, request, fcl.DistanceResult()))
        assert closest > 0.0
