"""The narrow phase: exact distances for the last bound level, and the verdict.

Two libraries answer here, one call per row. coal gives the exact distance between the two
bodies: first with meshes as their convex hulls (cheap), then, where that is not enough, as
their triangles, which settles pairs near concave meshes where every cheaper level only bounds
the distance to a hull or a box. It is level 4 of the bounds (`EXACT_MARGIN` less, for GJK's
tolerance). python-fcl gives the verdict, its collision
test, so that a check agrees with a per-state FCL loop; FCL's distances are never used as bounds
(python-fcl 0.7 overestimates some by centimetres), only as a heuristic for planners' clearance
checks. Calls are counted per thread.
"""

from __future__ import annotations

import threading

import coal
import fcl
import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.bodies import ExactBodies, Posed, RobotGeometry, SceneGeometry
from trajcache.geometry.model.shapes import FloatArray

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

# Subtracted from coal's distances: ten times its GJK tolerance (1e-6), in metres.
EXACT_MARGIN = 1e-5


class Narrow:
    """coal and FCL queries on rows of one robot and one scene, the robot posed per row."""

    def __init__(self, robot: RobotGeometry, scene: SceneGeometry) -> None:
        self.robot = robot
        self.scene = scene
        self._counts = threading.local()
        self._collide = fcl.CollisionRequest()

    @property
    def calls(self) -> int:
        """coal and FCL calls made by this thread so far."""
        return int(getattr(self._counts, "calls", 0))

    def _count(self, calls: int) -> None:
        self._counts.calls = self.calls + calls

    def scene_exact(
        self, posed: Posed, rows: IntArray, need: FloatArray | float = np.inf
    ) -> FloatArray:
        """Level 4 for scene rows: coal's distance between element and object, less
        `EXACT_MARGIN` (≤ 0 where they touch).

        Meshes are measured as their convex hulls first (a lower bound, and several times
        cheaper); where that is not above `need` (per row) or not positive, as their triangles.
        """
        if len(rows) == 0:
            return np.zeros(0)
        poses = posed.pose(rows[:, 0], rows[:, 1])
        placed = [coal.Transform3s(p[:3, :3], p[:3, 3]) for p in poses]
        scene = self.scene
        return self._exact(
            (self.robot.exact, rows[:, 1], placed),
            (scene.exact, rows[:, 2], [scene.placements[m] for m in rows[:, 2].tolist()]),
            need,
        )

    def self_exact(
        self, posed: Posed, rows: IntArray, need: FloatArray | float = np.inf
    ) -> FloatArray:
        """Level 4 for robot pairs, as `scene_exact`."""
        if len(rows) == 0:
            return np.zeros(0)
        robot = self.robot
        first, second = robot.pair_i[rows[:, 1]], robot.pair_j[rows[:, 1]]
        sides = []
        for element in (first, second):
            poses = posed.pose(rows[:, 0], element)
            sides.append(
                (robot.exact, element, [coal.Transform3s(p[:3, :3], p[:3, 3]) for p in poses])
            )
        return self._exact(sides[0], sides[1], need)

    def _exact(
        self,
        first: tuple[ExactBodies, IntArray, list[coal.Transform3s]],
        second: tuple[ExactBodies, IntArray, list[coal.Transform3s]],
        need: FloatArray | float,
    ) -> FloatArray:
        """coal's distances, row by row, of bodies `first` and `second` (their geometries, the
        index of each row's body and its placement), hulls first, less `EXACT_MARGIN`."""
        (bodies_a, index_a, placed_a), (bodies_b, index_b, placed_b) = first, second
        pairs = list(zip(index_a.tolist(), index_b.tolist(), strict=True))
        request = coal.DistanceRequest()
        out = np.empty(len(pairs))
        for k, (a, b) in enumerate(pairs):
            out[k] = coal.distance(
                bodies_a.hull[a], placed_a[k], bodies_b.hull[b], placed_b[k], request,
                coal.DistanceResult(),
            )  # fmt: skip
        differs = bodies_a.differs[index_a] | bodies_b.differs[index_b]
        refine = differs & (out <= np.maximum(need, 0.0))
        for k in np.flatnonzero(refine).tolist():
            a, b = pairs[k]
            out[k] = coal.distance(
                bodies_a.exact[a], placed_a[k], bodies_b.exact[b], placed_b[k], request,
                coal.DistanceResult(),
            )  # fmt: skip
        self._count(len(pairs) + int(refine.sum()))
        return out - EXACT_MARGIN

    def first_collision(
        self,
        posed: Posed,
        scene_rows: IntArray,
        self_rows: IntArray,
        *,
        stop_at_first: bool,
        every_contact: bool = False,
        pads: tuple[FloatArray, FloatArray] | None = None,
    ) -> tuple[BoolArray, BoolArray, BoolArray, BoolArray]:
        """FCL's exact collision test of rows, in state order (the verdict plain checks give).

        Returns per-row hit flags for both lists, then per-row "within the pad" flags. A row
        with a pad > 0 (`pads`, per row of each list) is first asked for FCL's distance, which
        settles it when larger than the pad (a clearance heuristic for planners: FCL's
        distances can be too large; certification never uses them). With `stop_at_first`
        nothing after the first colliding state is tested; without `every_contact` a state's
        other rows are skipped once one of them collides.
        """
        hits = (np.zeros(len(scene_rows), dtype=bool), np.zeros(len(self_rows), dtype=bool))
        near = (np.zeros(len(scene_rows), dtype=bool), np.zeros(len(self_rows), dtype=bool))
        pad_lists = (pads[0].tolist(), pads[1].tolist()) if pads is not None else None
        at: dict[int, int] = {}  # both share the robot's objects and so where they are
        posers = (
            _Poser(self, posed, scene_rows, scene=True, at=at),
            _Poser(self, posed, self_rows, scene=False, at=at),
        )
        order = np.concatenate([scene_rows[:, 0], self_rows[:, 0]])
        states = order.tolist()
        hit_state = -1
        calls = 0
        split = len(scene_rows)
        distance = fcl.DistanceRequest()
        for k in np.argsort(order, kind="stable").tolist():
            state = states[k]
            if stop_at_first and 0 <= hit_state < state:
                break
            if state == hit_state and not every_contact:
                continue
            group, row = (0, k) if k < split else (1, k - split)
            a, b = posers[group].pair(row)
            pad = pad_lists[group][row] if pad_lists is not None else 0.0
            if pad > 0.0:
                calls += 1
                if fcl.distance(a, b, distance, fcl.DistanceResult()) > pad:
                    continue
                near[group][row] = True
            calls += 1
            if fcl.collide(a, b, self._collide, fcl.CollisionResult()) > 0:
                hits[group][row] = True
                hit_state = state
        self._count(calls)
        return hits[0], hits[1], near[0], near[1]


class _Poser:
    """Poses this thread's FCL element objects for rows, all poses computed in one call.

    `at` records the sample each element's object was last put at during this call.
    """

    def __init__(
        self,
        narrow: Narrow,
        posed: Posed,
        rows: IntArray,
        *,
        scene: bool,
        at: dict[int, int],
    ) -> None:
        robot = narrow.robot
        self.objects = robot.objects()
        self.scene_objects = narrow.scene.objects
        self.rows = rows
        self.scene = scene
        sample = rows[:, 0]
        self.elements: tuple[IntArray, ...] = (rows[:, 1],)
        if not scene:
            self.elements = (robot.pair_i[rows[:, 1]], robot.pair_j[rows[:, 1]])
        self.poses = tuple(posed.pose(sample, e) for e in self.elements) if len(rows) else ()
        self.at = at

    def pair(self, k: int) -> tuple[fcl.CollisionObject, fcl.CollisionObject]:
        """The two FCL objects of row k, the robot's posed for it."""
        first = self._place(0, k)
        if self.scene:
            return first, self.scene_objects[int(self.rows[k, 2])]
        return first, self._place(1, k)

    def _place(self, which: int, k: int) -> fcl.CollisionObject:
        element = int(self.elements[which][k])
        obj = self.objects[element]
        key = int(self.rows[k, 0])
        if self.at.get(element) != key:
            pose = self.poses[which][k]
            obj.setTranslation(pose[:3, 3])
            obj.setRotation(pose[:3, :3])
            self.at[element] = key
        return obj
