"""The narrow phase: exact distances for the last bound level, and the verdict.

Level 4 of the bounds bounds the distance between the two bodies of each row as convex shapes,
meshes as their convex hulls: a compiled GJK whose every answer is a slab bound, so a proved
lower bound (`compiled/gjk.py`; `EXACT_MARGIN` less, for round-off), which stops as soon as it
exceeds what the row needs. Where that is not enough and a mesh's hull strays from it far
enough that its triangles could be (`Shape.hull_gap`), coal measures its triangles, one call
per row, which settles pairs where every cheaper level only bounds the distance to a hull or a
box (`EXACT_MARGIN` less, for coal's GJK tolerance). python-fcl gives
the verdict, its collision test, so that a check agrees with a per-state FCL loop; FCL's
distances are never used as bounds (python-fcl 0.7 overestimates some by centimetres), only as
a heuristic for planners' clearance checks. Calls (rows bounded, meshes measured, FCL queries)
are counted per thread.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import coal
import fcl
import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.bodies import ExactBodies, Posed, RobotGeometry, SceneGeometry
from trajcache.geometry.collision.compiled.gjk import TOLERANCE, convex_lower_rows
from trajcache.geometry.model.shapes import FloatArray

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
# One side of exact rows: its support table (`SupportTable.kernel_args`), each row's shape and
# world pose (K, 4, 4).
_Side = tuple[tuple[np.ndarray, ...], IntArray, FloatArray]
# coal's bodies of both sides (the second built on first use) and their hull gaps.
_Bodies = tuple[ExactBodies, Callable[[], ExactBodies], FloatArray, FloatArray]

# Subtracted from coal's distances: ten times its GJK tolerance (1e-6), in metres.
EXACT_MARGIN = 1e-5


def _convex(first: _Side, second: _Side, need: FloatArray) -> FloatArray:
    """GJK's lower bounds (`compiled/gjk.py`) of the rows of `first` and `second`, each
    stopping once above need[k]."""
    (sup_a, index_a, poses_a), (sup_b, index_b, poses_b) = first, second
    out = np.empty(len(index_a))
    convex_lower_rows(
        np.ascontiguousarray(poses_a), sup_a, index_a, np.ascontiguousarray(poses_b), sup_b,
        index_b, np.ascontiguousarray(need, dtype=float), np.empty((4, 3)), out,
    )  # fmt: skip
    return out


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
        self,
        posed: Posed,
        rows: IntArray,
        need: FloatArray | float = np.inf,
        *,
        past_need: bool = False,
    ) -> FloatArray:
        """Level 4 for scene rows: a lower bound of the distance between element and object,
        less `EXACT_MARGIN` (≤ 0 where they touch).

        Every row is first bounded as convex shapes, meshes as their hulls (compiled GJK,
        `compiled/gjk.py`), which stops once its bound exceeds `need` (per row); where it does
        not, a mesh is measured as its triangles (coal) if its hull strays from them at all,
        or, `past_need`, only if that could lift the bound past `need` (a caller that needs
        no bound below `need` to be as tight as it can be: the certifier's).
        """
        if len(rows) == 0:
            return np.zeros(0)
        robot, scene = self.robot, self.scene
        bodies = (robot.exact, lambda: scene.exact, robot.gaps, scene.gaps)
        return self._exact(*self._sides(posed, rows), (need, past_need), bodies)

    def self_exact(
        self,
        posed: Posed,
        rows: IntArray,
        need: FloatArray | float = np.inf,
        *,
        past_need: bool = False,
    ) -> FloatArray:
        """Level 4 for robot pairs, as `scene_exact`."""
        if len(rows) == 0:
            return np.zeros(0)
        robot = self.robot
        bodies = (robot.exact, lambda: robot.exact, robot.gaps, robot.gaps)
        return self._exact(*self._sides(posed, rows), (need, past_need), bodies)

    def convex_bounds(self, posed: Posed, rows: IntArray, need: FloatArray) -> FloatArray:
        """Lower bounds of scene rows (state, element, object) or robot-pair rows (state,
        pair), as convex shapes alone (meshes as their hulls; compiled GJK, no triangles),
        less `EXACT_MARGIN`: each stops once above need[k]."""
        out = _convex(*self._sides(posed, rows), need)
        self._count(len(rows))
        return out - EXACT_MARGIN

    def _sides(self, posed: Posed, rows: IntArray) -> tuple[_Side, _Side]:
        """Both sides of scene rows (state, element, object: the element, the object) or of
        robot-pair rows (state, pair: its two elements), posed."""
        robot = self.robot
        sup = robot.support.kernel_args
        if rows.shape[1] == 3:
            scene = self.scene
            element = (sup, rows[:, 1], posed.pose(rows[:, 0], rows[:, 1]))
            return element, (scene.support.kernel_args, rows[:, 2], scene.poses[rows[:, 2]])
        i, j = robot.pair_i[rows[:, 1]], robot.pair_j[rows[:, 1]]
        return (sup, i, posed.pose(rows[:, 0], i)), (sup, j, posed.pose(rows[:, 0], j))

    def _exact(
        self,
        first: _Side,
        second: _Side,
        wanted: tuple[FloatArray | float, bool],
        bodies: _Bodies,
    ) -> FloatArray:
        """Lower bounds of the distances of the rows of bodies `first` and `second` (their
        support tables, each row's body and world pose), as convex shapes (compiled), then
        as triangles where the bound is not above `need` (or 0) and the hull gaps leave room for
        the triangles' to be (`wanted`: the need, and whether past it); less `EXACT_MARGIN`."""
        (_, index_a, poses_a), (_, index_b, poses_b) = first, second
        need, past_need = wanted
        count = len(index_a)
        needs = np.ascontiguousarray(np.broadcast_to(np.asarray(need, dtype=float), (count,)))
        out = _convex(first, second, needs)
        exact_a, exact_b, gaps_a, gaps_b = bodies
        # The triangles' distance exceeds the hulls' by at most their gaps (`Shape.hull_gap`).
        enough = np.maximum(needs, 0.0)
        gap = gaps_a[index_a] + gaps_b[index_b]
        lifts = (gap > 0.0) & (out <= enough)
        if past_need:
            lifts &= out + gap + TOLERANCE > enough
        refine = np.flatnonzero(lifts)
        if len(refine):
            meshes_a, meshes_b = exact_a.exact, exact_b().exact
            request = coal.DistanceRequest()
            for k in refine.tolist():
                a, b = poses_a[k], poses_b[k]
                out[k] = coal.distance(
                    meshes_a[index_a[k]], coal.Transform3s(a[:3, :3], a[:3, 3]),
                    meshes_b[index_b[k]], coal.Transform3s(b[:3, :3], b[:3, 3]),
                    request, coal.DistanceResult(),
                )  # fmt: skip
        self._count(count + len(refine))
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
