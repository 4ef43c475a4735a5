"""Warming: compile (or load from numba's cache) every geometry kernel before a request needs it.

`planning/warm.py` calls `warm()` and then warms the compiled planner's kernels; the service
calls that when it starts, the Celery worker before it forks its processes, `make setup` once to
fill numba's on-disk cache, and the planner pool's forkserver through `trajcache.jobs.preload`.
"""

from __future__ import annotations

import numpy as np

from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.collision.compiled.spheres import sphere_state
from trajcache.geometry.collision.sphere_tables import sphere_tables
from trajcache.geometry.model.kernels import hull_support_climb
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
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


def warm() -> None:
    """Compile (or load from numba's cache) every kernel now, through the code that calls them
    (so with the argument types a request passes): certified validation, a state check with
    pads, a planner's quick motion check and a sphere-cover state check, of a small robot
    near a box and a mesh."""

    vertices = np.zeros((1, 3))
    index = np.zeros(1, dtype=np.int64)
    hull_support_climb(
        vertices, index, index + 1, index, index, index + 1, index, np.zeros(2, dtype=np.int64),
        index, np.zeros((1, 3)), np.zeros(1),
    )  # fmt: skip
    model, scene = warm_problem()
    key = np.array([[-1.5, 0.0], [1.5, 0.1]])
    validator = TrajectoryValidator(model, scene)
    validator.validate(key)
    validator.certifier.settled_by_bounds(key)
    checker = CollisionChecker(model, scene)
    checker.check(key, element_pad=np.full((2, len(model.elements)), 0.01),
                  pair_pad=np.full((2, len(checker.robot.pair_i)), 0.01))  # fmt: skip
    tables = sphere_tables(checker)
    sphere_state(key[0], tables.fk, tables.robot, tables.scene, tables.pairs, tables.work())


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
