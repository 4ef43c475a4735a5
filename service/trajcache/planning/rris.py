"""RRIS — Recursive Random Intermediate State (Medvid & Yakovyna 2025), the paper's planner.

As implemented here:
1. If the straight segment start → goal is free, the path is [start, goal].
2. Otherwise a colliding segment a → b is split at an intermediate state m. Candidates are
   drawn around the segment's midpoint (Gaussian, std = `spread` × |b − a|, at least
   `min_radius`) plus a share of uniform samples from the whole space; candidates in collision
   are dropped, and the one whose two halves a → m and m → b have the fewest colliding samples
   in total wins (ties: the shorter detour). `plan_with_rris` counts on every 4th sample (all
   candidates' halves in one batched call) and confirms a half at full resolution before it
   keeps it as free.
3. Each half that still collides is split the same way, recursively; a free half is kept as it
   is (early exit). Deeper than `max_depth`, or out of time, the attempt fails.
4. A failed attempt is repeated from scratch (`restarts`), each time with a wider spread (the
   spread grows by `spread_growth` per restart, cycling back after four), until a path is
   found or the budget runs out.

The function is pure: geometry comes in as callables, time as a Deadline, randomness as a
numpy Generator; failure is None. `plan_with_rris` wires it to a robot model and a scene.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import TrajectoryValidator
from trajcache.planning.attempts import Finisher, plan_until_certified
from trajcache.planning.deadline import Deadline
from trajcache.planning.motion import SHORTCUT_CLEARANCE_M
from trajcache.planning.options import SearchOptions
from trajcache.planning.problem import PlanResult
from trajcache.planning.query import Query, prepare_query

SegmentFn = Callable[[FloatArray, FloatArray], bool]
SegmentCountFn = Callable[[FloatArray, FloatArray], int]
SegmentsCountFn = Callable[[FloatArray, FloatArray], NDArray[np.int64]]
StatesFreeFn = Callable[[FloatArray], NDArray[np.bool_]]
SampleFn = Callable[[np.random.Generator], FloatArray]
SampleNearFn = Callable[[FloatArray, float, np.random.Generator], FloatArray]
InterpolateFn = Callable[[FloatArray, FloatArray, float], FloatArray]
DistanceFn = Callable[[FloatArray, FloatArray], float]

SCORE_STRIDE = 4  # candidates are scored on every 4th sample of their two halves


def _linear(a: FloatArray, b: FloatArray, t: float) -> FloatArray:
    start = np.asarray(a, dtype=float)
    return start + t * (np.asarray(b, dtype=float) - start)


def _euclidean(a: FloatArray, b: FloatArray) -> float:
    return float(np.linalg.norm(np.asarray(b, dtype=float) - np.asarray(a, dtype=float)))


def _gaussian_near(center: FloatArray, radius: float, g: np.random.Generator) -> FloatArray:
    return np.asarray(center, dtype=float) + g.normal(0.0, radius, len(center))


def _counts_each(
    segment_collisions_fn: SegmentCountFn, starts: FloatArray, ends: FloatArray
) -> NDArray[np.int64]:
    """Batched counts from the one-segment count, segment by segment."""
    return np.array([segment_collisions_fn(s, e) for s, e in zip(starts, ends, strict=True)])


def _free_each(segment_collisions_fn: SegmentCountFn, states: FloatArray) -> NDArray[np.bool_]:
    """Which states are free, each checked as a segment of length zero."""
    return np.array([segment_collisions_fn(s, s) == 0 for s in states], dtype=bool)


@dataclass
class _Search:
    """The callables and settings of one RRIS run (so the recursion stays small)."""

    segment_free: SegmentFn
    segment_counts: SegmentsCountFn
    counts_exact: bool
    states_free: StatesFreeFn
    sample: SampleFn
    sample_near: SampleNearFn
    interpolate: InterpolateFn
    distance: DistanceFn
    budget: Deadline
    rng: np.random.Generator
    max_depth: int
    samples: int
    uniform_share: float
    min_radius: float

    def restart(
        self, a: FloatArray, b: FloatArray, *, spread: float, growth: float, restarts: int
    ) -> list[FloatArray] | None:
        """Split a → b from scratch, the spread `growth` times wider each attempt (cycling after
        four), until a path is found; None when the attempts or the budget run out."""
        for attempt in range(restarts):
            if self.budget.expired():
                return None
            path = self.split(a, b, 0, spread * growth ** (attempt % 4))
            if path:
                return path
        return None

    def split(self, a: FloatArray, b: FloatArray, depth: int, spread: float) -> list[FloatArray]:
        """Waypoints a … b whose segments are free, or [] when this attempt fails."""
        if depth >= self.max_depth or self.budget.expired():
            return []
        radius = max(spread * self.distance(a, b), self.min_radius)
        mid = self.interpolate(a, b, 0.5)
        uniform = round(self.samples * self.uniform_share)
        candidates = np.array(
            [self.sample_near(mid, radius, self.rng) for _ in range(self.samples - uniform)]
            + [self.sample(self.rng) for _ in range(uniform)]
        )
        candidates = candidates[self.states_free(candidates)]
        if len(candidates) == 0:
            return []
        k = len(candidates)
        counts = self.segment_counts(
            np.concatenate([np.repeat(a[None, :], k, 0), candidates]),
            np.concatenate([candidates, np.repeat(b[None, :], k, 0)]),
        )
        left, right = counts[:k], counts[k:]
        detour = np.array([self.distance(a, m) + self.distance(m, b) for m in candidates])
        best = int(np.lexsort((detour, left + right))[0])
        m = candidates[best]
        head = [a, m] if self._free(a, m, left[best]) else self.split(a, m, depth + 1, spread)
        if not head:
            return []
        tail = [m, b] if self._free(m, b, right[best]) else self.split(m, b, depth + 1, spread)
        if not tail:
            return []
        return head + tail[1:]

    def _free(self, a: FloatArray, b: FloatArray, count: int) -> bool:
        """A half with no counted collision is free (confirmed when counts are approximate)."""
        return count == 0 and (self.counts_exact or self.segment_free(a, b))


@dataclass(frozen=True)
class RrisGeometry:
    """The space and the checks RRIS searches with, as callables.

    The batched variants `states_free_fn` and `segments_collisions_fn` are used when given;
    without them candidates are checked one by one (`segment_collisions_fn(m, m)` checks m).
    `counts_exact=False` says the counts only look at some samples (a cheaper score): a half
    with a zero count is then confirmed with `segment_free_fn` before it is kept.
    """

    segment_free_fn: SegmentFn
    segment_collisions_fn: SegmentCountFn
    sample_fn: SampleFn
    sample_near_fn: SampleNearFn | None = None
    interpolate_fn: InterpolateFn = _linear
    distance_fn: DistanceFn = _euclidean
    states_free_fn: StatesFreeFn | None = None
    segments_collisions_fn: SegmentsCountFn | None = None
    counts_exact: bool = True


@dataclass(frozen=True)
class RrisOptions:
    """How RRIS splits and restarts (see the module's docstring)."""

    max_depth: int = 6
    samples_per_split: int = 8
    uniform_share: float = 0.25
    spread: float = 0.3
    spread_growth: float = 1.6
    min_radius: float = 0.05
    restarts: int = 1000


def plan_rris(
    start: FloatArray,
    goal: FloatArray,
    geometry: RrisGeometry,
    *,
    budget: Deadline,
    rng: np.random.Generator,
    options: RrisOptions = RrisOptions(),
) -> list[FloatArray] | None:
    """Waypoints start … goal with free straight segments between them, or None."""
    a, b = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    g = geometry
    if g.segment_free_fn(a, b):
        return [a, b]
    search = _Search(
        segment_free=g.segment_free_fn,
        segment_counts=g.segments_collisions_fn or partial(_counts_each, g.segment_collisions_fn),
        counts_exact=g.counts_exact or g.segments_collisions_fn is None,
        states_free=g.states_free_fn or partial(_free_each, g.segment_collisions_fn),
        sample=g.sample_fn,
        sample_near=g.sample_near_fn or _gaussian_near,
        interpolate=g.interpolate_fn,
        distance=g.distance_fn,
        budget=budget,
        rng=rng,
        max_depth=options.max_depth,
        samples=max(1, options.samples_per_split),
        uniform_share=options.uniform_share,
        min_radius=options.min_radius,
    )
    return search.restart(
        a, b, spread=options.spread, growth=options.spread_growth, restarts=options.restarts
    )


def plan_with_rris(
    model: RobotModel,
    scene: Scene,
    start: Sequence[float] | FloatArray,
    goal: Sequence[float] | FloatArray,
    options: SearchOptions,
) -> PlanResult:
    """Plan with RRIS for a robot in a scene; SOLVED paths passed the validator that
    `options.resolution` and `options.certified` set up.

    A path that fails certification is repaired, or searched for again, while the budget lasts
    (`attempts.plan_until_certified`).
    """
    budget_s, resolution, certified = options.budget_s, options.resolution, options.certified
    deadline = Deadline(budget_s)
    began = time.perf_counter()
    prepared = prepare_query(model, scene, start, goal, resolution=resolution)
    if isinstance(prepared, PlanResult):
        return prepared
    query = prepared
    rng = np.random.default_rng(options.seed)
    validator = TrajectoryValidator(model, scene, resolution=resolution, certified=certified)
    endpoints_ms = (time.perf_counter() - began) * 1e3
    stats = {"plan_ms": endpoints_ms, "endpoints_ms": endpoints_ms}

    def search(attempt: int, deadline: Deadline) -> list[FloatArray] | None:
        path = rris_search(query, deadline, rng)
        stats["straight"] = float(path is not None and len(path) == 2)
        return path

    finisher = Finisher(
        query=query,
        validator=validator,
        segment_fn=query.checker.segment_certified
        if certified
        else partial(query.checker.segment_free, clearance=SHORTCUT_CLEARANCE_M),
        detour_fn=lambda q, d, certify: rris_search(q, d, rng, segment_free_fn=certify),
        deadline=deadline,
        rng=rng,
        shortcut_s=options.shortcut_s,
        stats=stats,
    )
    result = plan_until_certified(
        finisher, search_fn=search, none_found=f"RRIS found no path within {budget_s:.3g} s"
    )
    stats.update(query.checker.stats())
    stats["total_ms"] = (time.perf_counter() - began) * 1e3
    return result


def rris_search(
    query: Query,
    deadline: Deadline,
    rng: np.random.Generator,
    *,
    segment_free_fn: SegmentFn | None = None,
) -> list[FloatArray] | None:
    """RRIS on a prepared query, with the batched checks of its MotionChecker; a half is kept
    when `segment_free_fn` passes it (by default the checker's sample check)."""
    spec, checker = query.spec, query.checker
    geometry = RrisGeometry(
        segment_free_fn=segment_free_fn or checker.segment_free,
        segment_collisions_fn=checker.segment_collisions,
        sample_fn=spec.sample,
        sample_near_fn=spec.sample_near,
        interpolate_fn=spec.interpolate,
        distance_fn=spec.distance,
        states_free_fn=checker.states_free,
        segments_collisions_fn=partial(checker.segments_collisions, stride=SCORE_STRIDE),
        counts_exact=segment_free_fn is None and SCORE_STRIDE == 1,  # else confirm halves
    )
    return plan_rris(query.start, query.goal, geometry, budget=deadline, rng=rng)
