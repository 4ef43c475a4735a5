"""Compiled kernels (numba, `cache=True`) for the hot loops of the distance bounds.

The hull support climb lives here; the certification levels and forward kinematics are in
`compiled.py`. All are compiled once per machine (numba's on-disk cache, filled by `make setup`)
and warmed by `warm()` when the service starts, so that no request pays for compilation.
"""

from __future__ import annotations

import numba
import numpy as np

from trajcache.geometry.shapes import FloatArray


@numba.njit(cache=True, nogil=True)
def hull_support_climb(
    vertices: FloatArray,
    start: np.ndarray,
    count: np.ndarray,
    anchors: np.ndarray,
    anchor_start: np.ndarray,
    anchor_count: np.ndarray,
    neighbours: np.ndarray,
    neighbour_start: np.ndarray,
    slot: np.ndarray,
    local: FloatArray,
    out: FloatArray,
) -> None:  # pragma: no cover - compiled
    """out[q] = max over the vertices v of hull slot[q] of local[q]·v, for every q with a slot
    ≥ 0 (hull s's vertices packed at vertices[start[s] : start[s] + count[s]]), by hill
    climbing: from the best of the hull's anchor vertices, move to a neighbour (along a hull
    edge) while that raises local[q]·v.

    Exact for a convex polytope: a vertex that no edge improves maximizes a linear function
    over the polytope (the simplex method's optimality argument). `neighbours[neighbour_start[v]
    : neighbour_start[v + 1]]` are the packed indices of the vertices that share an edge with
    packed vertex v; a hull's anchors are packed vertex indices too.
    """
    for q in range(slot.shape[0]):
        s = slot[q]
        if s >= 0:
            out[q] = hull_climb(
                vertices, anchors, anchor_start, anchor_count, neighbours, neighbour_start, s,
                local[q, 0], local[q, 1], local[q, 2],
            )  # fmt: skip


@numba.njit(cache=True, nogil=True)
def hull_climb(
    vertices: FloatArray,
    anchors: np.ndarray,
    anchor_start: np.ndarray,
    anchor_count: np.ndarray,
    neighbours: np.ndarray,
    neighbour_start: np.ndarray,
    s: int,
    x: float,
    y: float,
    z: float,
) -> float:  # pragma: no cover - compiled
    """max over the vertices v of hull s of (x, y, z)·v, by the climb `hull_support_climb`
    describes (one direction; also called from the certification kernels)."""
    best = -np.inf
    at = -1
    for a in range(anchor_start[s], anchor_start[s] + anchor_count[s]):
        v = anchors[a]
        value = x * vertices[v, 0] + y * vertices[v, 1] + z * vertices[v, 2]
        if value > best:
            best = value
            at = v
    moved = True
    while moved:
        moved = False
        for n in range(neighbour_start[at], neighbour_start[at + 1]):
            v = neighbours[n]
            value = x * vertices[v, 0] + y * vertices[v, 1] + z * vertices[v, 2]
            if value > best:
                best = value
                at = v
                moved = True
    return best


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
    pads and a planner's quick motion check, of a small robot near a box and a mesh."""
    # Imported here: the geometry modules import this one.
    from trajcache.geometry.collision import CollisionChecker
    from trajcache.geometry.scene import SceneObject, make_scene
    from trajcache.geometry.shapes import Shape, ShapeKind
    from trajcache.geometry.urdf import load_robot_model
    from trajcache.geometry.validation import TrajectoryValidator

    vertices = np.zeros((1, 3))
    index = np.zeros(1, dtype=np.int64)
    hull_support_climb(
        vertices, index, index + 1, index, index, index + 1, index, np.zeros(2, dtype=np.int64),
        index, np.zeros((1, 3)), np.zeros(1),
    )  # fmt: skip
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
    key = np.array([[-1.5, 0.0], [1.5, 0.1]])
    validator = TrajectoryValidator(model, scene)
    validator.validate(key)
    validator.certifier.settled_by_bounds(key)
    checker = CollisionChecker(model, scene)
    checker.check(key, element_pad=np.full((2, len(model.elements)), 0.01),
                  pair_pad=np.full((2, len(checker.robot.pair_i)), 0.01))  # fmt: skip


def _placed(x: float, y: float, z: float) -> FloatArray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose
