"""Conservative advancement: settling the pairs no bound level could certify on a segment.

For a pair on a piece [t_a, t_b] of a segment, with distance lower bounds d_a, d_b at its ends
and a bound M on the pair's relative motion over the whole segment, the piece's motion bound is
M·(t_b − t_a) and the distance is positive wherever the bound from one end still is: near t_a
while d_a − M·(t − t_a) > 0, near t_b likewise. The rest, [t_a + d_a/M, t_b − d_b/M] in segment
fractions, is split in its middle (kept within the middle half of the piece, so pieces shrink
at least by a quarter) and both halves are tried again with the bounds at the new state (the
cheap levels first, coal's exact distance only where they fall short). It ends in a
certificate, in a state where FCL finds a contact, or - once a piece's motion bound falls below
`min_pad`, or after `max_depth` rounds - in TOO_CLOSE.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.bodies import Posed
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.validation.segments import Finding, OpenPairs, SegmentStatus

BoolArray = NDArray[np.bool_]


class Advancer:
    """Conservative advancement for one checker (model and scene)."""

    def __init__(self, checker: CollisionChecker, *, min_pad: float, max_depth: int) -> None:
        self.checker = checker
        self.robot = checker.robot
        self.clearance = checker.clearance
        self.narrow = checker.narrow
        self.min_pad = min_pad
        self.max_depth = max_depth

    def advance(self, states: FloatArray, delta: FloatArray, left: OpenPairs) -> Finding:
        """Conservative advancement on `left`, on segments of `states` (differences `delta`)."""
        start, end = np.zeros(len(left.rows)), np.ones(len(left.rows))
        probes = 0
        for _depth in range(self.max_depth):
            if len(left.rows) == 0:
                return Finding(SegmentStatus.FREE, subdivisions=probes)
            seg, lower_a, lower_b = left.rows[:, 0], left.lower_a, left.lower_b
            motion = left.motion * (end - start)
            if np.any(motion < self.min_pad):
                return self._too_close(
                    left, int(np.argmax(motion < self.min_pad)), start, end, probes
                )
            frac = (lower_a / motion + 1.0 - lower_b / motion) / 2.0
            mid = start + (end - start) * np.clip(frac, 0.25, 0.75)
            need = np.maximum(
                left.motion * (mid - start) - lower_a, left.motion * (end - mid) - lower_b
            )
            lower_m, hit = self._probe(states[seg] + mid[:, None] * delta[seg], left, need)
            probes += len(seg)
            if hit.any():
                k = int(np.argmin(np.where(hit, seg + mid, np.inf)))
                contact = self.checker.contact(left.rows[k], scene=left.scene)
                return Finding(
                    SegmentStatus.COLLISION, int(seg[k]), float(mid[k]), [contact], probes
                )
            keep = np.concatenate(
                [
                    lower_a + lower_m <= left.motion * (mid - start),
                    lower_m + lower_b <= left.motion * (end - mid),
                ]
            )
            left = OpenPairs(
                left.scene,
                np.concatenate([left.rows, left.rows]),
                np.concatenate([lower_a, lower_m]),
                np.concatenate([lower_m, lower_b]),
                np.concatenate([left.motion, left.motion]),
            ).take(keep)
            start = np.concatenate([start, mid])[keep]
            end = np.concatenate([mid, end])[keep]
        if len(left.rows) == 0:
            return Finding(SegmentStatus.FREE, subdivisions=probes)
        return self._too_close(left, 0, start, end, probes)

    def _probe(
        self, states: FloatArray, left: OpenPairs, need: FloatArray
    ) -> tuple[FloatArray, BoolArray]:
        """Bound of each pair at its own probe state, and whether FCL finds a contact there.

        The levels stop for a pair as soon as its bound exceeds `need`.
        """
        cl = self.clearance
        posed = Posed.build(self.robot, states)
        rows = left.rows.copy()
        rows[:, 0] = np.arange(len(rows))
        lower = np.maximum(
            cl.scene_slabs(posed, rows) if left.scene else cl.self_slabs(posed, rows), 0.0
        )
        weak = lower <= need
        if np.any(weak):
            if left.scene:
                balls = cl.scene_spheres(posed, rows[weak])
                better = np.maximum(
                    balls.lower.min(axis=1), cl.scene_cover_slabs(posed, rows[weak], balls)
                )
            else:
                pairs = cl.self_spheres(posed, rows[weak])
                better = np.maximum(
                    pairs.lower.min(axis=(1, 2)), cl.self_cover_slabs(posed, rows[weak], pairs)
                )
            lower[weak] = np.maximum(lower[weak], better)
            weak = lower <= need
        if np.any(weak):
            exact = self.narrow.scene_exact if left.scene else self.narrow.self_exact
            bound = exact(posed, rows[weak], need[weak], past_need=True)
            lower[weak] = np.maximum(lower[weak], bound)
        hit = np.zeros(len(rows), dtype=bool)
        zero = lower <= 0.0
        if np.any(zero):
            empty = np.empty((0, rows.shape[1]), dtype=np.int64)
            tests = (rows[zero], empty) if left.scene else (empty, rows[zero])
            found = self.narrow.first_collision(posed, *tests, stop_at_first=False)[:2]
            hit[zero] = found[0] if left.scene else found[1]
        return lower, hit

    def _too_close(
        self, left: OpenPairs, k: int, start: FloatArray, end: FloatArray, probes: int
    ) -> Finding:
        """TOO_CLOSE in the middle of the k-th open piece, naming its pair."""
        contact = self.checker.contact(left.rows[k], scene=left.scene)
        at = float(start[k] + end[k]) / 2.0
        return Finding(SegmentStatus.TOO_CLOSE, int(left.rows[k, 0]), at, [contact], probes)
