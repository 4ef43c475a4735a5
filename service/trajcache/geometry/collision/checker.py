"""Batched collision checking of robot states against a scene and against the robot itself.

A check bounds every (state, element, object) and (state, element pair) distance from below,
compiled (`compiled.state_rows_kernel`: world boxes, element balls, then support-function slabs
with meshes as boxes, then as hulls; with `compiled=False` the numpy levels of `clearance.py`),
and asks FCL only about the rows no bound clears.
The verdict is FCL's own collision test for those rows, so it agrees with a per-state FCL loop.

Clearance, for planners: with `pad` > 0 a row counts as AMBIGUOUS when no bound clears it by
more than the pad, FCL's distance is at most the pad and FCL finds no contact. That is a
heuristic (FCL's distances can be too large); certified validation does not use pads.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.bodies import Posed, RobotGeometry, SceneGeometry
from trajcache.geometry.collision.clearance import Clearance
from trajcache.geometry.collision.compiled import state_rows_kernel
from trajcache.geometry.collision.narrow import Narrow
from trajcache.geometry.collision.shared import GeometryCache, robot_geometry, scene_geometry
from trajcache.geometry.model.kinematics import check_states
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import Scene

__all__ = [
    "AMBIGUOUS",
    "COLLIDING",
    "FREE",
    "BatchVerdict",
    "CollisionChecker",
    "Contact",
    "ContactKind",
    "RobotGeometry",
    "SceneGeometry",
    "robot_geometry",
    "scene_geometry",
]

IntArray = NDArray[np.int64]

FREE, AMBIGUOUS, COLLIDING = 1, 0, -1
_FEW_ROWS = 48  # fewer candidate rows than this go straight to FCL


class ContactKind(str, Enum):
    """What a robot link touched."""

    SCENE = "scene"
    SELF = "self"


@dataclass(frozen=True)
class Contact:
    """One colliding pair: a robot link and a scene object id or another link."""

    link: str
    other: str
    kind: ContactKind

    def describe(self) -> str:
        """Human-readable form used in error messages."""
        what = "object" if self.kind is ContactKind.SCENE else "link"
        return f"link '{self.link}' hits {what} '{self.other}'"


@dataclass
class BatchVerdict:
    """Per-state outcome of a batch check: FREE, AMBIGUOUS or COLLIDING, and the first contact."""

    status: NDArray[np.int8]
    first_collision: int  # index of the first colliding state, or -1
    contacts: list[Contact]
    narrow_checks: int


class CollisionChecker:
    """Checks batches of states of one robot model in one scene."""

    def __init__(
        self,
        model: RobotModel,
        scene: Scene,
        *,
        compiled: bool = True,
        geometry: GeometryCache | None = None,
        self_collision: bool = True,
    ) -> None:
        self.model = model
        self.compiled = compiled  # the bounds of `compiled/`; else the numpy levels
        # False: only the scene is checked, for states whose self-collision is proven elsewhere
        # (a certificate, `validation/certificates.py`)
        self.self_collision = self_collision
        self.robot = robot_geometry(model, geometry)  # None: this process's shared geometry
        self.scene = scene_geometry(scene, geometry)
        self.clearance = Clearance(self.robot, self.scene)
        allowed = self.clearance.allowed
        self._allowed = np.zeros((0, 0), dtype=bool) if allowed is None else allowed
        self.narrow = Narrow(self.robot, self.scene)
        self._contacts: dict[tuple[int, int], Contact] = {}  # (element, object) or (pair, -1)

    @property
    def kernel_pairs(self) -> tuple[np.ndarray, ...]:
        """The self-collision pairs the compiled levels check: none without `self_collision`."""
        pairs = self.robot.kernel_pairs
        if self.self_collision:
            return pairs
        return tuple(p[..., :0] if k >= 3 else p[:0] for k, p in enumerate(pairs))

    @property
    def narrow_checks(self) -> int:
        """FCL calls made by this thread so far."""
        return self.narrow.calls

    def pose(self, states: FloatArray) -> Posed:
        """Forward kinematics of a batch of states, as the bounds use it."""
        return Posed.build(self.robot, check_states(self.model, states))

    def element_poses(self, states: FloatArray) -> FloatArray:
        """World poses (N, E, 4, 4) of every collision element."""
        return self.pose(states).elements

    def check(
        self,
        states: FloatArray,
        *,
        element_pad: FloatArray | None = None,
        pair_pad: FloatArray | None = None,
        stop_at_first: bool = True,
        every_contact: bool = False,
    ) -> BatchVerdict:
        """Classify each state; pads are (N, E) per element and (N, P) per self-collision pair.

        A colliding state's contacts are all of its contacts with `every_contact`, else the
        first one FCL finds.
        """
        posed = self.pose(states)
        n = len(posed.states)
        before = self.narrow.calls
        padded = element_pad is not None or pair_pad is not None
        epad = np.zeros((n, len(self.robot.radius))) if element_pad is None else element_pad
        ppad = np.zeros((n, len(self.robot.pair_i))) if pair_pad is None else pair_pad
        status = np.full(n, FREE, dtype=np.int8)
        scene_rows, self_rows, scene_pad, self_pad = self._candidates(posed, epad, ppad)
        if not self.self_collision:
            self_rows, self_pad = self_rows[:0], self_pad[:0]
        if len(scene_rows) == 0 and len(self_rows) == 0:
            return BatchVerdict(status, -1, [], self.narrow.calls - before)
        hit_scene, hit_self, near_scene, near_self = self.narrow.first_collision(
            posed,
            scene_rows,
            self_rows,
            stop_at_first=stop_at_first,
            every_contact=every_contact,
            pads=(scene_pad, self_pad) if padded else None,
        )
        status[scene_rows[near_scene, 0]] = AMBIGUOUS
        status[self_rows[near_self, 0]] = AMBIGUOUS
        status[scene_rows[hit_scene, 0]] = COLLIDING
        status[self_rows[hit_self, 0]] = COLLIDING
        colliding = np.flatnonzero(status == COLLIDING)
        first = int(colliding[0]) if len(colliding) else -1
        if stop_at_first and first >= 0:
            status[first + 1 :] = FREE  # not looked at past the first collision
        contacts = [self._contact(r, scene=True) for r in scene_rows[hit_scene]]
        contacts += [self._contact(r, scene=False) for r in self_rows[hit_self]]
        contacts.sort(key=lambda item: item[0])
        return BatchVerdict(
            status=status,
            first_collision=first,
            contacts=[c for _, c in contacts],
            narrow_checks=self.narrow.calls - before,
        )

    def _candidates(
        self, posed: Posed, epad: FloatArray, ppad: FloatArray
    ) -> tuple[IntArray, IntArray, FloatArray, FloatArray]:
        """The scene rows (state, element, object) and pair rows (state, pair) that no bound
        clears by more than their pad, with those pads: FCL's to decide."""
        if self.compiled:
            rg = self.robot
            scene_rows, self_rows = state_rows_kernel(
                posed.links,
                rg.kernel_robot,
                rg.element_half,
                rg.support.kernel_args,
                rg.kernel_motion,
                self.scene.kernel_scene,
                self.scene.support.kernel_args,
                self._allowed,
                self.kernel_pairs,
                np.ascontiguousarray(epad, dtype=float),
                np.ascontiguousarray(ppad, dtype=float),
            )
            scene_pad = epad[scene_rows[:, 0], scene_rows[:, 1]]
            self_pad = ppad[self_rows[:, 0], self_rows[:, 1]]
            # Level 4, as convex shapes (GJK): a row whose bound exceeds its pad is clear by
            # more than it, so FCL would find it neither colliding nor near.
            if len(scene_rows):
                keep = self.narrow.convex_bounds(posed, scene_rows, scene_pad) <= scene_pad
                scene_rows, scene_pad = scene_rows[keep], scene_pad[keep]
            if len(self_rows):
                keep = self.narrow.convex_bounds(posed, self_rows, self_pad) <= self_pad
                self_rows, self_pad = self_rows[keep], self_pad[keep]
            return scene_rows, self_rows, scene_pad, self_pad
        cl = self.clearance
        scene_rows = cl.scene_ball_rows(posed, np.asarray(epad, dtype=float))
        self_rows = np.argwhere(cl.self_balls(posed) <= ppad)
        scene_pad = epad[scene_rows[:, 0], scene_rows[:, 1]]
        self_pad = ppad[self_rows[:, 0], self_rows[:, 1]]
        if len(scene_rows) >= _FEW_ROWS:
            scene_rows, scene_pad = self._filter(posed, scene_rows, scene_pad)
        if len(self_rows) >= _FEW_ROWS:
            self_rows, self_pad = self._filter(posed, self_rows, self_pad)
        return scene_rows, self_rows, scene_pad, self_pad

    def _filter(self, posed: Posed, rows: IntArray, pad: FloatArray) -> tuple[IntArray, FloatArray]:
        """Level 2: the rows (and their pads) whose slab bounds stay within the pad. It pays off
        for more than a few rows (below that FCL takes them all); level 3 settles too few of
        what is left to pay for itself here."""
        cl = self.clearance
        bound = cl.scene_slabs(posed, rows) if rows.shape[1] == 3 else cl.self_slabs(posed, rows)
        keep = bound <= pad
        return rows[keep], pad[keep]

    def _contact(self, row: IntArray, *, scene: bool) -> tuple[int, Contact]:
        key = (int(row[1]), int(row[2])) if scene else (int(row[1]), -1)
        found = self._contacts.get(key)
        if found is None:
            names = self.model.link_names
            rg = self.robot
            if scene:
                link = names[rg.element_link[key[0]]]
                found = Contact(link=link, other=self.scene.ids[key[1]], kind=ContactKind.SCENE)
            else:
                li, lj = rg.element_link[rg.pair_i[key[0]]], rg.element_link[rg.pair_j[key[0]]]
                found = Contact(link=names[li], other=names[lj], kind=ContactKind.SELF)
            self._contacts[key] = found
        return int(row[0]), found

    def contact(self, row: IntArray, *, scene: bool) -> Contact:
        """The contact a scene row (state, element, object) or pair row (state, pair) names."""
        return self._contact(row, scene=scene)[1]

    def state_contacts(self, state: FloatArray) -> list[Contact]:
        """Every contact of one state (for error messages naming links and objects)."""
        verdict = self.check(
            np.asarray(state, dtype=float)[None, :], stop_at_first=False, every_contact=True
        )
        unique: dict[tuple[str, str], Contact] = {}
        for c in verdict.contacts:
            unique.setdefault((c.link, c.other), c)
        return list(unique.values())
