"""Warming: compile (or load from numba's cache) every geometry kernel before a request needs it.

`warm_steps` names the kernel groups in order; `planning/warm.py` adds the compiled planner's
after them. The service warms them all when it starts, the Celery worker before it forks its
processes, `trajcache warm` (and so `make setup`) once to fill numba's on-disk cache, and the
planner pool's forkserver through `trajcache.jobs.preload`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from trajcache.geometry.collision.bodies import Posed
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.collision.compiled.spheres import sphere_state
from trajcache.geometry.collision.sphere_tables import sphere_tables
from trajcache.geometry.model.kernels import hull_support_climb
from trajcache.geometry.model.nearness import relevant_rows
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.path_quality import ee_path_length
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.geometry.validation.end_clearance import open_intervals
from trajcache.geometry.validation.validator import TrajectoryValidator

_WARM_URDF = """<robot name="warm">
  <link name="base"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="arm"><collision><origin xyz="0 0 0.2"/>
    <geometry><cylinder radius="0.02" length="0.3"/></geometry></collision></link>
  <link name="hand"><collision><geometry><sphere radius="0.03"/></geometry></collision></link>
  <joint name="a" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="b" type="prismatic"><parent link="arm"/><child link="hand"/>
    <origin xyz="0 0 0.4"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.1" effort="1" velocity="1"/></joint>
</robot>"""
_KEY = np.array([[-1.5, 0.0], [1.5, 0.1]])  # two states of the small robot, both free


WarmStep = tuple[str, Callable[[], None]]  # (the kernels' group, the call that warms them)


def warm_steps() -> list[WarmStep]:
    """The geometry's kernel groups in the order they are warmed, each through the code that
    calls them (so with the argument types a request passes), on a small robot near a box and
    a mesh: the distance bounds, certified validation, a state check with pads and a planner's
    quick motion check, and a sphere-cover state check."""
    problem = functools.cache(warm_problem)

    @functools.cache
    def checker() -> CollisionChecker:
        return CollisionChecker(*problem())

    return [
        ("distance bounds", _warm_bounds),
        ("certified validation", lambda: _warm_validation(*problem())),
        ("collision checks", lambda: _warm_checks(checker())),
        ("sphere checks", lambda: _warm_spheres(checker())),
    ]


def warm() -> None:
    """Compile (or load from numba's cache) every geometry kernel now (`warm_steps`)."""
    for _, run in warm_steps():
        run()


def _warm_bounds() -> None:
    for writable in (True, False):  # the index's delta, and its main block (read-only keys)
        keys = np.zeros((1, 4))  # the cache's relevance test, one key of a two-dof robot
        keys.flags.writeable = writable
        relevant_rows(keys, np.zeros(1, dtype=np.int64), np.zeros((2, 4)), 0.2, False, False)
    vertices = np.zeros((1, 3))
    index = np.zeros(1, dtype=np.int64)
    hull_support_climb(
        vertices, index, index + 1, index, index, index + 1, index, np.zeros(2, dtype=np.int64),
        index, np.zeros((1, 3)), np.zeros(1),
    )  # fmt: skip


def _warm_validation(model: RobotModel, scene: Scene) -> None:
    validator = TrajectoryValidator(model, scene)
    validator.validate(_KEY)
    validator.certifier.settled_by_bounds(_KEY)
    posed = Posed.build(validator.checker.robot, _KEY)  # the exact level (compiled GJK)
    validator.checker.narrow.scene_exact(posed, np.ones((1, 3), dtype=np.int64))
    ee_path_length(model, _KEY)  # every answer's quality
    one, two = np.zeros((1, 1)), np.zeros((1, 2))  # one interval, element and pair; two dofs
    open_intervals(np.array([0.0, 1.0]), one, one, _KEY[0].copy(), _KEY[1].copy(), two, two)


def _warm_checks(checker: CollisionChecker) -> None:
    checker.check(_KEY, element_pad=np.full((2, len(checker.model.elements)), 0.01),
                  pair_pad=np.full((2, len(checker.robot.pair_i)), 0.01))  # fmt: skip


def _warm_spheres(checker: CollisionChecker) -> None:
    tables = sphere_tables(checker)
    sphere_state(_KEY[0], tables.fk, tables.robot, tables.scene, tables.pairs, tables.work())


def warm_problem() -> tuple[RobotModel, Scene]:
    """The small robot (a revolute and a prismatic joint) near a box and a mesh that warming
    checks."""
    model = load_robot_model(_WARM_URDF, name="warm")
    tetra = Shape(
        ShapeKind.MESH,
        vertices=np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]], dtype=float),
        faces=np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]], dtype=np.int64),
    )
    box = Shape(ShapeKind.BOX, (0.1, 0.1, 0.1))
    scene = make_scene(
        [
            SceneObject("box", box, _placed(0.25, 0.0, 0.4)),
            SceneObject("mesh", tetra, _placed(-0.25, 0.0, 0.4)),
        ]
    )
    return model, scene


def _placed(x: float, y: float, z: float) -> FloatArray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose
