"""Certifying that the straight motions between consecutive samples are free of collision.

For one segment and one pair (an element and a scene object, or two robot elements), let d_a and
d_b be lower bounds on the pair's distance at the two samples and M a bound on how far any point
of the pair moves relative to the other over the segment (`model/motion.py`). At a fraction t of the
segment the distance is at least max(d_a − t·M, d_b − (1 − t)·M) ≥ (d_a + d_b − M) / 2, so

    d_a + d_b > M  certifies the pair on the whole segment.

Pairs are settled level by level, dense and cheap first (`collision/clearance.py`): element balls
with the motion of their centre; slabs with the motion of the whole element (its centre's, plus its
ball radius times the turn of the dofs that move it); every ball of the sphere covers with its own
motion; the exact distance (coal, meshes as their triangles). The dense first level uses the
configuration-independent motion bound (one matrix product); the configuration-dependent one
is computed for the pairs it leaves. A segment with a pair left open is cut into pieces, each
certified the same way (`refine.py`). Then exact distances, and FCL's collision test where not
even they are positive at a sample: a colliding sample ends the search at once, as in the plain
check (a free one whose exact distance is positive needs no collision test). A pair no level
settles is conservative advancement's job (`advance.py`), which ends in a certificate, a
colliding state, or TOO_CLOSE. All of it is tried first in one compiled call (`settle.py`),
which certifies a chain or leaves it to these stages.

Every bound is a true bound (coal's exact distances less a margin for its tolerance; FCL
supplies the collision test, never a distance), so a certified motion has no collision anywhere
along it. A sample in collision always reaches FCL's collision test: there d = 0, its exact
bound is not positive, the other end's d ≤ M, and no level certifies its segments.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.bodies import Posed
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.collision.compiled import scene_open_kernel, self_open_kernel
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import segment_deltas
from trajcache.geometry.validation.advance import Advancer
from trajcache.geometry.validation.refine import PIECES, certify_in_pieces, restricted
from trajcache.geometry.validation.segments import (
    Finding,
    MovingPoints,
    OpenPairs,
    SegmentStatus,
    unique_rows,
)
from trajcache.geometry.validation.settle import ChainSettler

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
Groups = list[OpenPairs] | None  # open scene pairs, then robot pairs


@dataclass(frozen=True)
class _CoverLevel:
    """Level 3 on K rows: which it settles (K,), its lower bounds at both ends (2K,) and motion
    (K,), and the cover slabs at given ends (rows, a mask over both ends) of what it leaves."""

    settled: BoolArray
    lower: FloatArray
    motion: FloatArray
    slabs_fn: Callable[[IntArray, BoolArray], FloatArray]


MIN_PAD, MAX_DEPTH = 1e-4, 24  # the certifier's defaults


@dataclass(frozen=True)
class CertifierOptions:
    """How the certifier works: the smallest pad and deepest split of its advancer, and its
    compiled kernels or (`compiled=False`) the numpy levels of `clearance.py`, and the pieces
    a segment the levels leave open is cut into (`refine.py`; 1: none)."""

    min_pad: float = MIN_PAD
    max_depth: int = MAX_DEPTH
    compiled: bool = True  # and the compiled first try (`settle.py`)
    pieces: int = PIECES


class SegmentCertifier:
    """Certifies the segments between consecutive samples of one model in one scene."""

    def __init__(
        self,
        checker: CollisionChecker,
        *,
        base: BaseType,
        options: CertifierOptions = CertifierOptions(),
    ) -> None:
        self.checker = checker
        self.compiled, self.pieces = options.compiled, options.pieces
        self.robot = checker.robot
        self.clearance = checker.clearance
        self.narrow = checker.narrow
        self.base = base
        self.advancer = Advancer(checker, min_pad=options.min_pad, max_depth=options.max_depth)
        self.settler = ChainSettler(checker, min_pad=options.min_pad, max_depth=options.max_depth)
        rg = self.robot
        turning = rg.motion.rotation & rg.motion.ancestors
        self._turn = turning[rg.element_link].T.astype(float)  # (D, E)
        # Configuration-independent motion per unit step: element centres (D, E), pairs (D, P).
        self._centre_coef = rg.centre_coef.T.copy()
        self._pair_coef, self._pair_whole = rg.pair_motion()
        self._allowed = checker._allowed

    def certify(self, states: FloatArray, *, cut: bool = True, only: Groups = None) -> Finding:
        """Certify every segment of `states` (N ≥ 2); the earliest collision found stops it.
        With `cut`, open segments are cut into pieces before exact distances (`refine.py`),
        which certify only the pairs left `only` open on them (compiled levels)."""
        delta = segment_deltas(states, base=self.base)
        step = self.robot.motion.steps(delta)
        settled = self.settler.free(states, delta, step) if self.compiled and only is None else None
        if settled is not None:  # the compiled call certified it (`settle.py`)
            return Finding(SegmentStatus.FREE, subdivisions=settled)
        posed = Posed.build(self.robot, states)
        if self.compiled:
            groups = self._compiled_levels(posed, step, only=only)
        else:
            groups = [self._covers(posed, step, g) for g in self._dense(posed, step)]
            if not self.checker.self_collision:
                groups[1] = groups[1].take(np.zeros(len(groups[1].rows), dtype=bool))
        if not any(len(group.rows) for group in groups):
            return Finding(SegmentStatus.FREE)  # the usual case: every pair certified
        if cut and self.pieces > 1:  # the pieces hold every sample of the open segments
            piece_fn = functools.partial(self.certify, cut=False, only=groups)
            return certify_in_pieces(piece_fn, states, delta, groups, self.pieces)
        groups = [self._exact(posed, g) for g in groups]
        found = self._sample_collision(posed, groups)  # where not even they are positive
        if found.status is SegmentStatus.COLLISION:
            return found
        probes = 0
        for group in groups:
            deeper = self.advancer.advance(states, delta, group)
            probes += deeper.subdivisions
            if deeper.position < found.position:
                found = deeper
        found.subdivisions = probes
        return found

    def settled_by_bounds(self, states: FloatArray) -> bool:
        """True when the compiled levels alone certify every segment of `states` (N ≥ 2); they
        stop at the first pair they leave open. A quick yes for planners' motion checks."""
        posed = Posed.build(self.robot, states)
        step = self.robot.motion.steps(segment_deltas(states, base=self.base))
        return not any(len(g.rows) for g in self._compiled_levels(posed, step, first_only=True))

    def _compiled_levels(
        self, posed: Posed, step: FloatArray, *, first_only: bool = False, only: Groups = None
    ) -> list[OpenPairs]:
        """Levels 1 to 3 on every segment at once, compiled (`collision/compiled/`): what they
        leave open, scene pairs then robot pairs (with `first_only`, at most the first one
        found; with `only`, of the pairs open in those groups alone, `refine.py`)."""
        rg = self.robot
        step = np.ascontiguousarray(step, dtype=float)
        world, links, half, support = self.clearance.scene, posed.links, rg.element_half, rg.support
        allowed, pairs, pair_ids = self._allowed, self.checker.kernel_pairs, None
        if only is not None:
            allowed, pairs, pair_ids = restricted(
                only, allowed, (len(rg.radius), len(world.ids)), pairs
            )
        rows, lows = scene_open_kernel(
            links, step, rg.kernel_robot, half, support.kernel_args, rg.kernel_motion,
            world.kernel_scene, world.support.kernel_args, allowed, first_only,
        )  # fmt: skip
        scene = OpenPairs(True, rows, lows[:, 0], lows[:, 1], lows[:, 2])
        if (first_only and len(rows)) or (only is not None and len(pairs[0]) == 0):
            return [scene, OpenPairs(False, np.zeros((0, 2), np.int64), *np.zeros((3, 0)))]
        rows, lows = self_open_kernel(
            links, step, rg.kernel_robot, half, support.kernel_args, rg.kernel_motion,
            pairs, first_only,
        )  # fmt: skip
        if pair_ids is not None:
            rows[:, 1] = pair_ids[rows[:, 1]]
        return [scene, OpenPairs(False, rows, lows[:, 0], lows[:, 1], lows[:, 2])]

    def _dense(self, posed: Posed, step: FloatArray) -> tuple[OpenPairs, OpenPairs]:
        """Level 1 on every segment at once, with configuration-independent motion bounds: what
        the balls leave, with the (configuration-independent) motion of the whole elements."""
        rg, cl = self.robot, self.clearance
        centre = step @ self._centre_coef  # (N − 1, E)
        whole = centre + rg.radius * (step @ self._turn)
        grow = np.maximum(np.vstack([whole, whole[-1:]]), np.vstack([whole[:1], whole]))
        near = cl.near_objects(posed, grow)
        balls = np.maximum(cl.scene_balls(posed, near), 0.0)
        k, e, m = np.nonzero(balls[:-1] + balls[1:] <= centre[:, :, None])
        scene = OpenPairs(
            True, np.column_stack([k, e, near[m]]), balls[k, e, m], balls[k + 1, e, m], whole[k, e]
        )
        gaps = np.maximum(cl.self_balls(posed), 0.0)
        k, p = np.nonzero(gaps[:-1] + gaps[1:] <= step @ self._pair_coef)
        pair_whole = step[k] @ self._pair_whole  # (K, P)
        pairs = OpenPairs(
            False,
            np.column_stack([k, p]),
            gaps[k, p],
            gaps[k + 1, p],
            pair_whole[np.arange(len(p)), p],
        )
        return scene, pairs

    def _element_motion(self, posed: Posed, step: FloatArray, left: OpenPairs) -> FloatArray:
        """Configuration-dependent motion (K,) of the whole elements of the pairs `left`."""
        rg = self.robot
        seg, index = left.rows[:, 0], left.rows[:, 1]
        masks: list[FloatArray | None] = [None]
        elements = [index]
        if not left.scene:
            pair_mask = rg.pair_mask[index].astype(float)
            elements = [rg.pair_i[index], rg.pair_j[index]]
            masks = [pair_mask, pair_mask]
        whole = np.zeros(len(seg))
        for element, mask in zip(elements, masks, strict=True):
            points = MovingPoints(
                posed.centres[seg, element][:, None],
                posed.centres[seg + 1, element][:, None],
                rg.centre_coef[element][:, None],
                rg.radius[element][:, None],
            )
            _, w = self._point_motion(posed, step, seg, element, points, mask)
            whole += w[:, 0]
        return whole

    def _covers(self, posed: Posed, step: FloatArray, left: OpenPairs) -> OpenPairs:
        """Levels 2 and 3: the element's slabs, then every cover ball with its own motion; both
        ends of every segment go through one call per level."""
        if len(left.rows) == 0:
            return left
        left = self._slabs(posed, step, left)
        if len(left.rows) == 0:
            return left
        return self._cover_balls(posed, step, left)

    def _slabs(self, posed: Posed, step: FloatArray, left: OpenPairs) -> OpenPairs:
        """Level 2: slabs with meshes as their boxes, then as their hulls, then the
        configuration-dependent motion of the whole elements for what they leave."""
        cl = self.clearance
        slabs = cl.scene_slabs if left.scene else cl.self_slabs
        # Meshes as their boxes first (no hull query), then as their hulls for what is left.
        for exact in (False, True) if self.robot.support.has_hulls else (True,):
            k = len(left.rows)
            if k == 0:
                return left
            bound = slabs(posed, np.concatenate([left.rows, left.ends]), exact=exact)
            left.lower_a = np.maximum(left.lower_a, bound[:k])
            left.lower_b = np.maximum(left.lower_b, bound[k:])
            left = left.open()
        if len(left.rows):
            left.motion = np.minimum(left.motion, self._element_motion(posed, step, left))
            left = left.open()
        return left

    def _cover_balls(self, posed: Posed, step: FloatArray, left: OpenPairs) -> OpenPairs:
        """Level 3: every ball of the sphere covers with the motion of its own centre; where a
        ball is not settled, slabs along the ways the closest balls look (`_CoverLevel`)."""
        k = len(left.rows)
        both = np.concatenate([left.rows, left.ends])
        cover_level = self._scene_cover if left.scene else self._self_cover
        level = cover_level(posed, step, left, both)
        left.lower_a = np.maximum(left.lower_a, level.lower[:k])
        left.lower_b = np.maximum(left.lower_b, level.lower[k:])
        left.motion = np.minimum(left.motion, level.motion)
        open_ = np.concatenate([~level.settled, ~level.settled])
        cover = level.slabs_fn(both[open_], open_)
        left = left.take(~level.settled)
        k = len(left.rows)
        left.lower_a = np.maximum(left.lower_a, cover[:k])
        left.lower_b = np.maximum(left.lower_b, cover[k:])
        return left.open()

    def _scene_cover(
        self, posed: Posed, step: FloatArray, left: OpenPairs, both: IntArray
    ) -> _CoverLevel:
        """Level 3 for scene rows: the element's cover balls against the object."""
        cl, k, seg = self.clearance, len(left.rows), left.rows[:, 0]
        balls = cl.scene_spheres(posed, both)
        centre, whole = self._ball_motion(
            posed, step, seg, balls.centres[:k], balls.centres[k:], left.rows[:, 1]
        )
        low = np.maximum(balls.lower, 0.0)
        return _CoverLevel(
            settled=np.all(low[:k] + low[k:] > centre, axis=1),
            lower=low.min(axis=1),
            motion=whole.max(axis=1),
            slabs_fn=lambda rows, keep: cl.scene_cover_slabs(posed, rows, balls.subset(keep)),
        )

    def _self_cover(
        self, posed: Posed, step: FloatArray, left: OpenPairs, both: IntArray
    ) -> _CoverLevel:
        """Level 3 for robot pairs: every ball of one cover against every ball of the other."""
        cl, k, seg = self.clearance, len(left.rows), left.rows[:, 0]
        pairs = cl.self_spheres(posed, both)
        pair = left.rows[:, 1]
        mask = self.robot.pair_mask[pair].astype(float)
        ci, wi = self._ball_motion(
            posed, step, seg, pairs.first[:k], pairs.first[k:], self.robot.pair_i[pair], mask
        )
        cj, wj = self._ball_motion(
            posed, step, seg, pairs.second[:k], pairs.second[k:], self.robot.pair_j[pair], mask
        )
        low = np.maximum(pairs.lower, 0.0)
        return _CoverLevel(
            settled=np.all(low[:k] + low[k:] > ci[:, :, None] + cj[:, None, :], axis=(1, 2)),
            lower=low.min(axis=(1, 2)),
            motion=wi.max(axis=1) + wj.max(axis=1),
            slabs_fn=lambda rows, keep: cl.self_cover_slabs(posed, rows, pairs.subset(keep)),
        )

    def _ball_motion(
        self,
        posed: Posed,
        step: FloatArray,
        seg: IntArray,
        centres_a: FloatArray,
        centres_b: FloatArray,
        element: IntArray,
        mask: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """Per cover ball (K, S): the motion of its centre, and of any of its points."""
        rg = self.robot
        width = centres_a.shape[1]
        points = MovingPoints(
            centres_a,
            centres_b,
            rg.sphere_coef[element, :width],
            rg.sphere_radius[element, :width],
        )
        return self._point_motion(posed, step, seg, element, points, mask)

    def _point_motion(
        self,
        posed: Posed,
        step: FloatArray,
        seg: IntArray,
        element: IntArray,
        points: MovingPoints,
        mask: FloatArray | None,
    ) -> tuple[FloatArray, FloatArray]:
        """Motion (K, S) over segments `seg` of `points` of `element`, and of any point within
        their radius; with `mask` (K, D) only those dofs count."""
        motion = self.robot.motion
        at_a, at_b, coef, radius = points.at_a, points.at_b, points.coef, points.radius
        if mask is not None and not np.any(
            mask * motion.ancestors[self.robot.element_link[element]]
        ):
            zero = np.zeros(at_a.shape[:2])  # only dofs moving both alike: the pair's frame
            return zero, zero
        axes_a = (posed.axis_origins[seg, None], posed.axis_dirs[seg, None])
        axes_b = (posed.axis_origins[seg + 1, None], posed.axis_dirs[seg + 1, None])
        r_a = motion.axis_distances(at_a, axes_a)
        r_b = motion.axis_distances(at_b, axes_b)
        levers = motion.levers(r_a, r_b, coef, step[seg, None])
        turn = motion.turn(self.robot.element_link[element], step[seg])
        if mask is not None:
            levers, turn = levers * mask[:, None], turn * mask
        ones = np.ones(levers.shape[-1])
        centre = levers @ ones
        return centre, centre + radius * (turn @ ones)[:, None]

    def _sample_collision(self, posed: Posed, groups: list[OpenPairs]) -> Finding:
        """FCL's collision test at the ends where no bound is positive; the earliest hit wins.
        Like the plain check, a colliding sample ends the search at once: what lies between
        earlier samples is not looked at."""
        touching = []
        for group in groups:
            ends = np.concatenate(
                [group.rows[group.lower_a <= 0.0], group.ends[group.lower_b <= 0.0]]
            )
            touching.append(unique_rows(ends)[0] if len(ends) else ends)
        hit_scene, hit_self, *_ = self.narrow.first_collision(posed, *touching, stop_at_first=True)
        hits = [(int(r[0]), self.checker.contact(r, scene=True)) for r in touching[0][hit_scene]]
        hits += [(int(r[0]), self.checker.contact(r, scene=False)) for r in touching[1][hit_self]]
        if not hits:
            return Finding(SegmentStatus.FREE)
        sample = min(s for s, _ in hits)
        return Finding(SegmentStatus.COLLISION, sample, 0.0, [c for s, c in hits if s == sample])

    def _exact(self, posed: Posed, group: OpenPairs) -> OpenPairs:
        """Level 4, exact distances, at the ends of the pairs left (each end once)."""
        count = len(group.rows)
        if count == 0:
            return group
        both = np.concatenate([group.rows, group.ends])
        unique, where = unique_rows(both)
        need = np.zeros(len(unique))  # an end's bound settles its segment above the motion
        np.maximum.at(need, where, np.concatenate([group.motion, group.motion]))
        exact = self.narrow.scene_exact if group.scene else self.narrow.self_exact
        bound = exact(posed, unique, need, past_need=True)
        group.lower_a = np.maximum(group.lower_a, bound[where[:count]])
        group.lower_b = np.maximum(group.lower_b, bound[where[count:]])
        return group.open()
