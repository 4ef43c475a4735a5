"""State-space glue between a RobotModel and the planners: bounds, metric, steering, checks.

A state is (x, y, θ, q1 … qn) for a planar base, (q1 … qn) for a fixed one. θ is an angle
(SO(2)): differences, distances and interpolation take the short way round. `StateSpaceSpec`
holds the sampling bounds (base x, y from the scene's extent; joints from the model's limits)
and may hold some values constant (the base, when a query does not move it). `MotionChecker`
answers collision questions for states and for straight segments sampled at the paper's
resolution, one batched `CollisionChecker.check` call per question, and counts what it did.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.checker import COLLIDING, FREE, CollisionChecker
from trajcache.geometry.errors import StateError
from trajcache.geometry.model.kinematics import check_limits, check_states
from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import base_is_still as _base_is_still
from trajcache.geometry.model.space import path_length, state_steps, wrap_angle
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.segments import SegmentStatus
from trajcache.geometry.validation.validator import Resolution, TrajectoryValidator, interpolate
from trajcache.planning.problem import PlannerStatus, PlanResult

EMPTY_SCENE_MARGIN_M = 2.0  # base bounds around the query when the scene gives no extent
# TrajectoryValidator's default min_pad: closer than this, no motion can be certified.
CERTIFIABLE_CLEARANCE_M = 1e-4
# Shortcut segments hug obstacles; checked samples keep this clearance so that collisions
# between samples (which certified validation would find) stay rare.
SHORTCUT_CLEARANCE_M = 0.01
_SPREAD_SAMPLES = 8  # samples a certified motion check looks at before certifying in full


@dataclass(frozen=True, eq=False)
class StateSpaceSpec:
    """Sampling bounds and metric of one model's states; `held` values never change."""

    model: RobotModel
    lower: FloatArray
    upper: FloatArray
    resolution: Resolution = field(default_factory=Resolution)

    @property
    def planar(self) -> bool:
        """True when the state starts with a planar base pose (x, y, θ)."""
        return self.model.base is BaseType.PLANAR

    @property
    def dof(self) -> int:
        """Length of a state vector."""
        return self.model.dof

    @property
    def held(self) -> NDArray[np.bool_]:
        """Per state value: True when its bounds pin it to one value."""
        return np.asarray(self.upper - self.lower <= 0.0)

    def difference(self, a: FloatArray, b: FloatArray) -> FloatArray:
        """b − a with the base angle taking the short way (works on batches too)."""
        return state_steps(a, b, planar=self.planar)

    def distance(self, a: FloatArray, b: FloatArray) -> float:
        """Euclidean distance in state space, base angle wrapped."""
        return float(np.linalg.norm(self.difference(a, b)))

    def interpolate(self, a: FloatArray, b: FloatArray, t: float) -> FloatArray:
        """The state a fraction `t` of the way from a to b (the short way for θ)."""
        out = np.asarray(a, dtype=float) + t * self.difference(a, b)
        if self.planar:
            out[..., 2] = wrap_angle(out[..., 2])
        return out

    def extend(self, a: FloatArray, b: FloatArray) -> FloatArray:
        """Samples (N, D) of the segment at the paper resolution, a excluded, b included."""
        key = np.stack([np.asarray(a, dtype=float), np.asarray(b, dtype=float)])
        samples = interpolate(key, self.model, self.resolution)[1:]
        if self.planar:
            samples[:, 2] = wrap_angle(samples[:, 2])
        return samples

    def path_length(self, path: Sequence[FloatArray] | FloatArray) -> float:
        """Sum of the distances between consecutive states."""
        return path_length(path, planar=self.planar)

    def clip(self, state: FloatArray) -> FloatArray:
        """The state pulled inside the bounds (θ wrapped rather than clipped)."""
        out = np.asarray(state, dtype=float).copy()
        if self.planar:
            theta = out[..., 2].copy()
            out = np.clip(out, self.lower, self.upper)
            out[..., 2] = self.lower[2] if self.held[2] else wrap_angle(theta)
            return out
        return np.clip(out, self.lower, self.upper)

    def sample(self, rng: np.random.Generator) -> FloatArray:
        """A state drawn uniformly within the bounds."""
        out: FloatArray = self.lower + rng.random(self.dof) * (self.upper - self.lower)
        return out

    def sample_near(
        self, center: FloatArray, radius: float, rng: np.random.Generator
    ) -> FloatArray:
        """A state drawn from an isotropic Gaussian of std `radius` around `center`."""
        step = rng.normal(0.0, radius, self.dof)
        step[self.held] = 0.0
        return self.clip(np.asarray(center, dtype=float) + step)


def scene_extent(scene: Scene) -> tuple[FloatArray, FloatArray] | None:
    """The (x, y) axis-aligned box around every scene object, or None for an empty scene."""
    if not scene.objects:
        return None
    lows, highs = [], []
    for obj in scene.objects:
        reach = np.abs(obj.pose[:3, :3]) @ np.asarray(obj.shape.half_extents(), dtype=float)
        lows.append(obj.pose[:2, 3] - reach[:2])
        highs.append(obj.pose[:2, 3] + reach[:2])
    return np.min(lows, axis=0), np.max(highs, axis=0)


def state_space_spec(
    model: RobotModel,
    scene: Scene | None = None,
    *,
    base_bounds: tuple[Sequence[float], Sequence[float]] | None = None,
    hold_base: FloatArray | None = None,
    around: Sequence[FloatArray] = (),
    resolution: Resolution | None = None,
) -> StateSpaceSpec:
    """Bounds for planning: base (x, y) from `base_bounds`, else the scene's extent; joints from
    the model's limits. `hold_base` pins the base to that (x, y, θ); `around` states are always
    inside the bounds (a start a little outside the scene's extent stays plannable)."""
    lower, upper = model.lower.astype(float).copy(), model.upper.astype(float).copy()
    if model.base is BaseType.PLANAR:
        lower[2], upper[2] = -math.pi, math.pi
        if hold_base is not None:
            held = np.asarray(hold_base, dtype=float)[:3].copy()
            held[2] = float(wrap_angle(held[2]))
            lower[:3] = upper[:3] = held
        else:
            lo, hi = _base_box(scene, base_bounds, around)
            lower[:2], upper[:2] = lo, hi
    return StateSpaceSpec(model, lower, upper, resolution or Resolution())


def _base_box(
    scene: Scene | None,
    base_bounds: tuple[Sequence[float], Sequence[float]] | None,
    around: Sequence[FloatArray],
) -> tuple[FloatArray, FloatArray]:
    points = np.array([np.asarray(s, dtype=float)[:2] for s in around]).reshape(-1, 2)
    if base_bounds is not None:
        lo, hi = np.asarray(base_bounds[0], dtype=float), np.asarray(base_bounds[1], dtype=float)
    else:
        extent = scene_extent(scene) if scene is not None else None
        if extent is not None:
            lo, hi = extent
        elif len(points):
            lo = points.min(axis=0) - EMPTY_SCENE_MARGIN_M
            hi = points.max(axis=0) + EMPTY_SCENE_MARGIN_M
        else:
            lo, hi = np.full(2, -EMPTY_SCENE_MARGIN_M), np.full(2, EMPTY_SCENE_MARGIN_M)
    if len(points):
        lo, hi = np.minimum(lo, points.min(axis=0)), np.maximum(hi, points.max(axis=0))
    return lo, hi


def coarse_to_fine(count: int) -> NDArray[np.int64]:
    """A permutation of range(count) visiting the last, then every other sample, halving steps.

    Collisions span several neighbouring samples, so checking spread-out samples first lets a
    stop-at-first check end early.
    """
    index = np.arange(1, count + 1, dtype=np.int64)
    lowbit = index & -index
    if count:
        lowbit[-1] = np.iinfo(np.int64).max
    return np.argsort(-lowbit, kind="stable")


class MotionChecker:
    """Collision checks of states and straight segments of one model in one scene.

    Counts states checked, segments checked, calls into the collision checker and FCL narrow-
    phase checks. A segment's start is assumed valid (as in OMPL) and not checked again.
    """

    def __init__(self, spec: StateSpaceSpec, scene: Scene) -> None:
        self.spec = spec
        self.checker = CollisionChecker(spec.model, scene)
        self.states_checked = 0
        self.segments_checked = 0
        self.calls = 0
        self.certified_checks = 0
        self._validator: TrajectoryValidator | None = None

    @property
    def validator(self) -> TrajectoryValidator:
        """The certified validator at the spec's resolution (built on first use)."""
        if self._validator is None:
            self._validator = TrajectoryValidator(
                self.spec.model, self.checker.scene.scene, resolution=self.spec.resolution
            )
        return self._validator

    def segment_certified(self, a: FloatArray, b: FloatArray) -> bool:
        """True when the straight motion a → b is certified free: its samples are the ones
        validation takes on that segment (`validation.interpolate`), and the compiled bounds
        (or, for the few pairs they leave open, conservative advancement) prove every motion
        between them free. A path made of such motions passes certified validation.

        The compiled bounds answer first, stopping at the first pair they leave open; then a
        check of a few spread-out samples finds most blocked motions; only what neither settles
        is certified in full."""
        samples = interpolate(np.stack([a, b]), self.spec.model, self.spec.resolution)
        self.calls += 1
        self.segments_checked += 1
        self.certified_checks += 1
        self.states_checked += len(samples) - 1
        if len(samples) < 2:
            return True
        certifier = self.validator.certifier
        if certifier.settled_by_bounds(samples):  # the usual free motion
            return True
        spread = samples[1:][coarse_to_fine(len(samples) - 1)[:_SPREAD_SAMPLES]]
        if self.checker.check(spread, stop_at_first=True).first_collision >= 0:
            return False  # the usual blocked motion: a sample collides
        return certifier.certify(samples).status is SegmentStatus.FREE

    @property
    def narrow_checks(self) -> int:
        """FCL narrow-phase checks so far."""
        return self.checker.narrow_checks

    def stats(self) -> dict[str, float]:
        """The counters, for PlanResult.stats."""
        return {
            "checks": float(self.states_checked),
            "segment_checks": float(self.segments_checked),
            "check_calls": float(self.calls),
            "narrow_checks": float(self.narrow_checks),
            "certified_checks": float(self.certified_checks),
        }

    def state_free(self, state: FloatArray) -> bool:
        """True when one state is free of collision."""
        return bool(self.states_free(np.asarray(state, dtype=float)[None, :])[0])

    def states_free(self, states: FloatArray) -> NDArray[np.bool_]:
        """Per state: True when free (one batched call)."""
        arr = np.asarray(states, dtype=float)
        self.calls += 1
        self.states_checked += len(arr)
        verdict = self.checker.check(arr, stop_at_first=False)
        return np.asarray(verdict.status == FREE)

    def clearance_status(self, states: FloatArray, clearance: float) -> NDArray[np.int8]:
        """Per state: FREE beyond `clearance`, AMBIGUOUS within it, or COLLIDING."""
        arr = np.asarray(states, dtype=float)
        self.calls += 1
        self.states_checked += len(arr)
        element_pad, pair_pad = self._pads(len(arr), clearance)
        verdict = self.checker.check(
            arr, element_pad=element_pad, pair_pad=pair_pad, stop_at_first=False
        )
        return verdict.status

    @staticmethod
    def _strided(samples: FloatArray, stride: int) -> FloatArray:
        if stride <= 1 or len(samples) <= stride:
            return samples
        return samples[np.r_[np.arange(stride - 1, len(samples) - 1, stride), len(samples) - 1]]

    def _pads(self, count: int, clearance: float) -> tuple[FloatArray, FloatArray]:
        """Constant per-element and per-pair pads for `count` states."""
        elements, pairs = len(self.spec.model.elements), len(self.checker.robot.pair_i)
        return np.full((count, elements), clearance), np.full((count, pairs), clearance)

    def segment_samples(self, a: FloatArray, b: FloatArray) -> FloatArray:
        """The samples a segment check looks at, in coarse-to-fine order."""
        samples = self.spec.extend(a, b)
        return samples[coarse_to_fine(len(samples))]

    def segment_free(self, a: FloatArray, b: FloatArray, clearance: float = 0.0) -> bool:
        """True when every sample of a → b (a excluded) is free, and farther than `clearance`
        from obstacles and from the robot itself; stops at the first collision."""
        samples = self.segment_samples(a, b)
        self.calls += 1
        self.segments_checked += 1
        self.states_checked += len(samples)
        if clearance <= 0.0:
            return self.checker.check(samples, stop_at_first=True).first_collision < 0
        element_pad, pair_pad = self._pads(len(samples), clearance)
        verdict = self.checker.check(
            samples, element_pad=element_pad, pair_pad=pair_pad, stop_at_first=True
        )
        return bool(np.all(verdict.status == FREE))

    def segment_collisions(self, a: FloatArray, b: FloatArray) -> int:
        """How many samples of a → b (a excluded) collide."""
        return int(self.segments_collisions(np.asarray(a)[None, :], np.asarray(b)[None, :])[0])

    def segments_collisions(
        self, starts: FloatArray, ends: FloatArray, stride: int = 1
    ) -> NDArray[np.int64]:
        """Colliding-sample counts of many segments, all samples in one batched call; with
        `stride` > 1 only every stride-th sample (and the end) is looked at."""
        pieces = [
            self._strided(self.spec.extend(a, b), stride) for a, b in zip(starts, ends, strict=True)
        ]
        owner = np.repeat(np.arange(len(pieces)), [len(p) for p in pieces])
        samples = np.concatenate(pieces) if pieces else np.empty((0, self.spec.dof))
        self.calls += 1
        self.segments_checked += len(pieces)
        self.states_checked += len(samples)
        if len(samples) == 0:
            return np.zeros(len(pieces), dtype=np.int64)
        status = self.checker.check(samples, stop_at_first=False).status
        return np.bincount(owner[status == COLLIDING], minlength=len(pieces)).astype(np.int64)


@dataclass(eq=False)
class Query:
    """A checked planning query: endpoints, the bounds to plan in and the collision checker."""

    start: FloatArray
    goal: FloatArray
    spec: StateSpaceSpec
    checker: MotionChecker
    base_still: bool


def base_is_still(model: RobotModel, start: FloatArray, goal: FloatArray) -> bool:
    """True when a planar base has the same pose at both ends (always False for a fixed base);
    the tolerance is `geometry.model.space.BASE_STILL_TOLERANCE`."""
    return _base_is_still(start, goal, planar=model.base is BaseType.PLANAR)


def prepare_query(
    model: RobotModel,
    scene: Scene,
    start: Sequence[float] | FloatArray,
    goal: Sequence[float] | FloatArray,
    *,
    resolution: Resolution | None = None,
    hold_still_base: bool = True,
) -> Query | PlanResult:
    """Check the endpoints (length, limits, collisions) and build the space to plan in.

    Returns a PlanResult (INVALID_START / INVALID_GOAL) when an endpoint is unusable. When the
    base does not move between start and goal it is held there (`hold_still_base`).
    """
    ends: list[FloatArray] = []
    for name, state, bad in (
        ("start", start, PlannerStatus.INVALID_START),
        ("goal", goal, PlannerStatus.INVALID_GOAL),
    ):
        try:
            arr = check_states(model, state, name=name)[0]
            check_limits(model, arr, name=name)
        except StateError as exc:
            return PlanResult(bad, message=str(exc))
        ends.append(arr)
    s, g = ends
    still = hold_still_base and base_is_still(model, s, g)
    spec = state_space_spec(
        model, scene, hold_base=s if still else None, around=(s, g), resolution=resolution
    )
    checker = MotionChecker(spec, scene)
    status = checker.clearance_status(np.stack([s, g]), CERTIFIABLE_CLEARANCE_M)
    for k, (name, bad) in enumerate(
        (("start", PlannerStatus.INVALID_START), ("goal", PlannerStatus.INVALID_GOAL))
    ):
        if status[k] == COLLIDING:
            contacts = checker.checker.state_contacts(ends[k])
            text = "; ".join(c.describe() for c in contacts) or "collision"
            return PlanResult(bad, message=f"{name} is in collision: {text}")
        if status[k] != FREE:
            message = (
                f"{name} is within {CERTIFIABLE_CLEARANCE_M * 1e3:g} mm of an obstacle: "
                "no motion from it can be certified"
            )
            return PlanResult(bad, message=message)
    return Query(s, g, spec, checker, still)
