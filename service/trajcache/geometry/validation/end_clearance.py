"""Clearance certificates of a path's end segments: an adapted end segment proved free in O(E + P).

A hit serves a stored path with new first and last states; its interior is known (the memo, a
certificate), and its first and last segments are what is left to prove. Each is near the
stored segment it replaces, which was proved free in this scene. This module keeps, for a
certified segment, how far every robot element stayed from every scene object and every
checked pair of elements from each other, and proves the replacing segment from that alone.

The argument. Let x(t) = a + t·Δx, t ∈ [0, 1], be the stored segment, from a to b, and
y(t) = a' + t·Δy the adapted one, where Δ is the dof difference the validator interpolates
(the short way round for a base heading). Both are straight in joint space, so their
difference y(t) − x(t) = (a' − a) + t·(Δy − Δx) is affine in t, and each dof's |y_j(t) − x_j(t)|
is at most σ_j = max(|a'_j − a_j|, |a'_j + Δy_j − a_j − Δx_j|), its value at one end.
Moving from x(t) to y(t) in a straight line moves any point of element e by at most
m_e = Σ_j W_ej·σ_j, where W is the configuration-independent bound the certifier uses for a
whole element (its centre's lever arm per dof, plus its ball radius times the turn of the dofs
that move it: `RobotGeometry.kernel_robot`), and moves a pair's elements apart or together by
at most m_p = Σ_j V_pj·σ_j (the pair's whole-element bound, `RobotGeometry.pair_motion`).
Distance is 1-Lipschitz in the points of each body, so if every point of e stayed at least
C_e from every object along x, then along y it stays at least C_e − m_e away: the segment is
free of the scene wherever C_e > m_e for every element, and free of self-collision wherever
C_p > m_p for every checked pair. Joint limits hold along y when they hold at its two ends
(a box is convex), and the validator checks those states anyway.

The test is made interval by interval of the stored segment's samples: on [t_k, t_{k+1}] the
difference is at most its larger end value (|affine| is convex), and C_k holds there. The
intervals it leaves form one span [t_lo, t_hi] (from the first to the last unproved one), and
only the adapted segment's stretch y(t_lo) → y(t_hi), a straight motion itself, is validated
in full (`_validate_span`). A first segment ends where the stored one does (y(1) = x(1)), so
its far part is proved; a last segment starts where it does, so its near part is. With the
certificate audit on, every segment a clearance shortened is validated again in full, and a
disagreement raises (`validate_ends`).

C is measured on the stored segment by the validator's own samples x_k, its own geometry and
allowed pairs: at each sample a lower bound L_k per (element, object) and per pair (the
element balls, then coal's exact distance where the balls come within `CAP`; any bound above
`CAP` counts as `CAP`, still a lower bound), and between samples k and k + 1, where the element
moves by at most M_k, the distance is at least (L_k + L_{k+1} − M_k) / 2 (`certify.py`'s
argument): C_k, per element over every object, per pair.

It holds for the scene, variant and validator settings it was measured in, as the memo's
verdicts do (`cache/memo.py`): a clearance is kept under that scope only. Fixed bases only: a
planar base's adapted path is re-anchored, and its ends are validated in full.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np

from trajcache.geometry.collision.bodies import Posed, RobotGeometry
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import compiled_input, segment_deltas
from trajcache.geometry.validation.certificates import CertificateDisagreement
from trajcache.geometry.validation.sampling import interpolate
from trajcache.geometry.validation.validator import (
    TrajectoryValidator,
    ValidationResult,
    ValidationStatus,
)

__all__ = [
    "CAP",
    "SegmentClearance",
    "measure_clearance",
    "motion_tables",
    "open_intervals",
    "validate_ends",
]

CAP = 0.10  # m: clearance measured up to this; an adapted end moves no point further

_TABLES: weakref.WeakKeyDictionary[
    RobotGeometry, tuple[tuple[FloatArray, ...], FloatArray, FloatArray]
] = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class SegmentClearance:
    """Lower bounds on distances along one certified segment, interval by interval of its
    samples (at `fractions`, 0 to 1): per element to every scene object (K − 1, E), per checked
    robot pair (K − 1, P); all at most `CAP`."""

    fractions: FloatArray
    scene: FloatArray
    pairs: FloatArray

    def reversed(self) -> SegmentClearance:
        """The same bounds for the segment run backwards."""
        return SegmentClearance(1.0 - self.fractions[::-1], self.scene[::-1], self.pairs[::-1])

    def less(self, slack: float) -> SegmentClearance:
        """The bounds in a scene whose objects moved by at most `slack` (the robot pairs' do
        not change)."""
        return SegmentClearance(self.fractions, self.scene - slack, self.pairs)

    def unproved(
        self, checker: CollisionChecker, old: FloatArray, new: FloatArray
    ) -> tuple[float, float] | None:
        """The span of fractions of segment `new` (2, D) that these bounds of segment `old`
        leave to prove (module docstring); None when they prove all of it."""
        if checker.robot.model.base is not BaseType.FIXED:
            return 0.0, 1.0
        element, pair = motion_tables(checker.robot)
        if self.scene.shape[1] != len(element) or self.pairs.shape[1] not in (0, len(pair)):
            return 0.0, 1.0  # measured for other elements or pairs: proves nothing here
        first, last = open_intervals(
            compiled_input(self.fractions),
            compiled_input(self.scene),
            compiled_input(self.pairs),
            compiled_input(new[0] - old[0]),
            compiled_input(new[1] - old[1]),
            element,
            pair,
        )
        if first < 0:
            return None
        return float(self.fractions[first]), float(self.fractions[last + 1])


@numba.njit(cache=True, nogil=True, inline="always")
def _above(bounds, table, sigma):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether every bound (C,) exceeds its motion table row (C, D) times σ (D,); True for none."""
    for c in range(bounds.shape[0]):
        motion = 0.0
        for d in range(sigma.shape[0]):
            motion += sigma[d] * table[c, d]
        if not bounds[c] > motion:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def open_intervals(fractions, scene, pairs, d0, d1, element, pair):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The first and last interval k (of fractions[k] to fractions[k + 1]) where the bounds
    `scene` (K − 1, E) and `pairs` (K − 1, P; P may be 0) do not exceed the motion W·σ_k,
    V·σ_k (`element` (E, D), `pair` (P, D)) of a fixed-base segment whose ends differ from the
    measured one's by d0 and d1: σ_k, per dof, the larger of |d0 + t (d1 − d0)| at the
    interval's two fractions (module docstring); (−1, −1) when there is none."""
    n_dof = d0.shape[0]
    first = last = -1
    sigma = np.empty(n_dof)
    for k in range(fractions.shape[0] - 1):
        for d in range(n_dof):
            at_a = abs(d0[d] + fractions[k] * (d1[d] - d0[d]))
            at_b = abs(d0[d] + fractions[k + 1] * (d1[d] - d0[d]))
            sigma[d] = max(at_a, at_b)
        proved = _above(scene[k], element, sigma) and _above(pairs[k], pair, sigma)
        if not proved:
            first = k if first < 0 else first
            last = k
    return first, last


def measure_clearance(validator: TrajectoryValidator, segment: FloatArray) -> SegmentClearance:
    """C per interval, element and checked pair of `segment` (2, D), sampled as `validator`
    samples it; measured with its geometry and allowed pairs."""
    checker, model = validator.checker, validator.model
    samples = interpolate(segment, model, validator.resolution, validator.subdivision)
    robot = checker.robot
    posed = Posed.build(robot, samples)
    steps = robot.motion.steps(segment_deltas(samples, base=model.base))  # (K − 1, D)
    element_motion, pair_motion = motion_tables(robot)
    n, e = len(samples), len(robot.radius)
    at = np.full((n, e), CAP)
    rows = checker.clearance.scene_ball_rows(posed, np.full((n, e), CAP))
    if len(rows):
        exact = np.minimum(checker.narrow.scene_exact(posed, rows, CAP), CAP)
        np.minimum.at(at, (rows[:, 0], rows[:, 1]), exact)
    scene = _between(at, steps @ element_motion.T)
    pairs = np.full((n - 1, 0), CAP)
    if checker.self_collision and len(robot.pair_i):
        balls = checker.clearance.self_balls(posed)  # (K, P)
        pair_at = np.minimum(balls, CAP)
        sample, pair = np.nonzero(balls < CAP)
        if len(sample):
            near = np.column_stack([sample, pair])
            pair_at[sample, pair] = np.minimum(checker.narrow.self_exact(posed, near, CAP), CAP)
        pairs = _between(pair_at, steps @ pair_motion.T)
    return SegmentClearance(np.arange(n) / (n - 1), scene, pairs)


def _validate_span(
    validator: TrajectoryValidator, new: FloatArray, span: tuple[float, float] | None
) -> ValidationResult:
    """Validate the stretch `span` (fractions; None: nothing) of segment `new` (2, D)."""
    if span is None:
        return ValidationResult(ValidationStatus.VALID, 0, 0)
    lo, hi = span
    if (lo, hi) == (0.0, 1.0):
        return validator.validate_segments(new, [0])
    delta = segment_deltas(new, base=validator.model.base)[0]
    part = np.array([new[0] + lo * delta, new[0] + hi * delta])
    if lo == 0.0:
        part[0] = new[0]
    if hi == 1.0:
        part[1] = new[1]
    return validator.validate_segments(part, [0])


def _between(at: FloatArray, motion: FloatArray) -> FloatArray:
    """(L_k + L_{k+1} − M_k) / 2 per interval and column, at most `CAP`."""
    return np.asarray(np.minimum((at[:-1] + at[1:] - motion) / 2.0, CAP))


def motion_tables(robot: RobotGeometry) -> tuple[FloatArray, FloatArray]:
    """W (E, D) and V (P, D): the most a point of an element, and a pair's distance, move per
    unit step of each dof, whatever the configuration (the certifier's whole-element bounds;
    the pairs as `kernel_pairs` holds them, those still checked); C-ordered, kept per robot
    while its pairs stay those."""
    kept = _TABLES.get(robot)
    if kept is None or kept[0] is not robot.kernel_pairs:
        turning = robot.motion.rotation & robot.motion.ancestors
        coef = robot.centre_coef + robot.radius[:, None] * turning[robot.element_link]
        element = np.ascontiguousarray(coef, dtype=float)
        pair = np.ascontiguousarray(robot.kernel_pairs[4].T, dtype=float)
        kept = _TABLES[robot] = (robot.kernel_pairs, element, pair)
    return kept[1], kept[2]


def validate_ends(
    validator: TrajectoryValidator,
    states: FloatArray,
    segments: list[int],
    *,
    stored: FloatArray,
    known: Callable[[FloatArray], SegmentClearance | None],
    audit: bool = False,
    proved: list[float] | None = None,
) -> ValidationResult:
    """`validator.validate_segments(states, segments)` for a path adapted from `stored` (as
    oriented, same length): each segment i only where the clearance `known(stored[i:i + 2])`
    leaves it unproved. With `audit`, a segment a clearance shortened is validated again in
    full, and a disagreement raises `CertificateDisagreement`. The share of each segment its
    clearance proved (0 without one) is appended to `proved`."""
    total = ValidationResult(ValidationStatus.VALID, 0, 0)
    for i in segments:
        old = stored[i : i + 2]
        clearance = known(old)
        new = states[i : i + 2]
        span = (0.0, 1.0) if clearance is None else clearance.unproved(validator.checker, old, new)
        result = _validate_span(validator, new, span)
        if proved is not None:
            proved.append(1.0 if span is None else 1.0 - (span[1] - span[0]))
        if audit and clearance is not None and result.valid:
            truth = validator.validate_segments(new, [0])
            if not truth.valid:
                raise CertificateDisagreement(
                    f"an end clearance passed segment {i}, which full validation finds "
                    f"{truth.status.value}: {truth.message}"
                )
        total = total.then(result)
        if not total.valid:
            break
    return total
