"""FCL's part of a check: nearest-point directions for the last bound level, and the verdict.

FCL answers two questions here, one call per row: which way the two bodies are nearest each
other (level 4 of `clearance.py` then bounds their distance along that line; FCL's own distance
value is not used, it can be too large), and whether they touch (FCL's collision test, the
verdict plain checks give, so that they agree with a per-state FCL loop). For planners'
clearance checks it also gives its distance value, as a heuristic. Calls are counted per thread.
"""

from __future__ import annotations

import threading

import fcl
import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.bodies import Posed, RobotGeometry, SceneGeometry
from trajcache.geometry.clearance import Clearance
from trajcache.geometry.shapes import FloatArray

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


class Narrow:
    """FCL queries on rows of one robot and one scene, the robot's objects posed per row."""

    def __init__(self, robot: RobotGeometry, scene: SceneGeometry, clearance: Clearance) -> None:
        self.robot = robot
        self.scene = scene
        self.clearance = clearance
        self._counts = threading.local()
        self._request = fcl.DistanceRequest(enable_nearest_points=True)
        self._collide = fcl.CollisionRequest()

    @property
    def fcl_calls(self) -> int:
        """FCL calls made by this thread so far."""
        return int(getattr(self._counts, "calls", 0))

    def _count(self, calls: int) -> None:
        self._counts.calls = self.fcl_calls + calls

    def scene_nearest(self, posed: Posed, rows: IntArray) -> FloatArray:
        """Level 4 for scene rows: the slab bound along FCL's nearest-point direction."""
        return self._nearest(posed, rows, scene=True)

    def self_nearest(self, posed: Posed, rows: IntArray) -> FloatArray:
        """Level 4 for robot pairs."""
        return self._nearest(posed, rows, scene=False)

    def _nearest(self, posed: Posed, rows: IntArray, *, scene: bool) -> FloatArray:
        # A mesh is queried as its convex hull: only the direction is used, and any direction
        # gives a valid slab.
        if len(rows) == 0:
            return np.zeros(0)
        dirs = np.zeros((len(rows), 1, 3))
        poser = _Poser(self, posed, rows, scene=scene, at={}, hulls=True)
        for k in range(len(rows)):
            first, second = poser.pair(k)
            result = fcl.DistanceResult()
            if fcl.distance(first, second, self._request, result) > 0.0:
                near_a, near_b = result.nearest_points
                dirs[k, 0] = np.asarray(near_b) - np.asarray(near_a)
        self._count(len(rows))
        slab = self.clearance.scene_slab if scene else self.clearance.self_slab
        return slab(posed, rows, dirs)

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
        hulls: bool = False,
    ) -> None:
        robot = narrow.robot
        self.objects = robot.objects(hulls=hulls)
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
