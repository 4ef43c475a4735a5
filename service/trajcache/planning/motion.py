"""Collision checks of states and straight motions, as OMPL's `MotionValidator`.

`MotionChecker` answers collision questions for states and for straight segments sampled at
the paper's resolution, one batched `CollisionChecker.check` call per question, and counts
what it did.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.checker import COLLIDING, FREE, CollisionChecker
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.segments import SegmentStatus
from trajcache.geometry.validation.validator import TrajectoryValidator, interpolate
from trajcache.planning.space import StateSpaceSpec

# TrajectoryValidator's default min_pad: closer than this, no motion can be certified.
CERTIFIABLE_CLEARANCE_M = 1e-4
# Shortcut segments hug obstacles; checked samples keep this clearance so that collisions
# between samples (which certified validation would find) stay rare.
SHORTCUT_CLEARANCE_M = 0.01
_SPREAD_SAMPLES = 8  # samples a certified motion check looks at before certifying in full


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
