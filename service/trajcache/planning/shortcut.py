"""Path shortcutting: a separate pass after planning, pure and bounded in time.

`shortcut` first drops redundant waypoints (a waypoint goes when its neighbours see each other),
then repeatedly picks two random points on the path, anywhere along its segments, and replaces
the stretch between them by a straight segment when that is free and shorter by a useful
margin (until it stops finding any), and finally drops redundant waypoints again. Every
segment it adds was checked with `segment_free_fn`, and every change shortens the path, so it
never lengthens a path nor creates a segment that was not checked.

`shortcut_and_certify` is the finishing pass shared by the planners: shortcut, then the final
(certified) validation; when the shortcut path fails it, the unshortened path is tried. When both
fail, the shortcut path comes back with the verdict, for `repair.repair_path` to mend.

Before validation, each candidate gets an anchor near each end (`anchor_ends`): a waypoint
`END_REACH` along its first and last segments. The motion is the same (the waypoint lies on the
segment), but a cache hit, which replaces a stored path's first and last states by the request's,
then proves only the short stretch from the request's start to the anchor (and from the anchor
to its goal) anew: the rest of the path is the stored path's own, certified in that scene.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from trajcache.geometry.model.shapes import FloatArray
from trajcache.planning.deadline import Deadline

SegmentFn = Callable[[FloatArray, FloatArray], bool]
DistanceFn = Callable[[FloatArray, FloatArray], float]
InterpolateFn = Callable[[FloatArray, FloatArray, float], FloatArray]
ValidateFn = Callable[[FloatArray], tuple[bool, str]]

_SAME = 1e-9  # two states closer than this are the same waypoint
END_REACH = 0.1  # how far along its first and last segments a path's end anchors lie
MIN_GAIN = 0.01  # a shortcut must save at least this share of the path's length
PATIENCE = 20  # random tries in a row without a shortcut before the random phase stops


def _linear(a: FloatArray, b: FloatArray, t: float) -> FloatArray:
    start = np.asarray(a, dtype=float)
    return start + t * (np.asarray(b, dtype=float) - start)


def path_length(path: Sequence[FloatArray], distance_fn: DistanceFn) -> float:
    """Sum of the distances between consecutive waypoints."""
    return float(sum(distance_fn(path[i], path[i + 1]) for i in range(len(path) - 1)))


def remove_redundant(
    path: Sequence[FloatArray], *, segment_free_fn: SegmentFn, deadline: Deadline | None = None
) -> list[FloatArray]:
    """One greedy pass: skip each waypoint whose predecessor sees its successor directly."""
    points = [np.asarray(p, dtype=float) for p in path]
    if len(points) < 3:
        return points
    kept = [points[0]]
    for k in range(1, len(points) - 1):
        if deadline is not None and deadline.expired():
            kept.extend(points[k:-1])
            break
        if not segment_free_fn(kept[-1], points[k + 1]):
            kept.append(points[k])
    kept.append(points[-1])
    return kept


def shortcut(
    path: Sequence[FloatArray],
    *,
    segment_free_fn: SegmentFn,
    distance_fn: DistanceFn,
    budget_s: float,
    rng: np.random.Generator,
    max_iters: int = 100,
    interpolate_fn: InterpolateFn = _linear,
) -> list[FloatArray]:
    """A path with the same end points, never longer, whose new segments were all checked.

    A shortcut is only tried when it would save at least `MIN_GAIN` of the current length;
    the random phase stops after `PATIENCE` tries in a row without a shortcut.
    """
    deadline = Deadline(budget_s)
    points = remove_redundant(path, segment_free_fn=segment_free_fn, deadline=deadline)
    idle = 0
    for _ in range(max_iters):
        if len(points) < 3 or deadline.expired() or idle >= PATIENCE:
            break
        idle += 1
        lengths = np.array([distance_fn(points[i], points[i + 1]) for i in range(len(points) - 1)])
        cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
        s1, s2 = np.sort(rng.uniform(0.0, cumulative[-1], 2))
        i = min(int(np.searchsorted(cumulative, s1, side="right")) - 1, len(lengths) - 1)
        j = min(int(np.searchsorted(cumulative, s2, side="right")) - 1, len(lengths) - 1)
        if i == j or lengths[i] <= 0.0 or lengths[j] <= 0.0:
            continue
        p1 = interpolate_fn(points[i], points[i + 1], (s1 - cumulative[i]) / lengths[i])
        p2 = interpolate_fn(points[j], points[j + 1], (s2 - cumulative[j]) / lengths[j])
        if distance_fn(p1, p2) > (s2 - s1) - MIN_GAIN * cumulative[-1]:
            continue
        if not segment_free_fn(p1, p2):
            continue
        idle = 0
        head = points[: i + 1] + ([p1] if distance_fn(points[i], p1) > _SAME else [])
        tail = ([p2] if distance_fn(p2, points[j + 1]) > _SAME else []) + points[j + 1 :]
        points = head + tail
    if not deadline.expired():
        points = remove_redundant(points, segment_free_fn=segment_free_fn, deadline=deadline)
    return points


def anchor_ends(
    path: Sequence[FloatArray], *, distance_fn: DistanceFn, interpolate_fn: InterpolateFn
) -> list[FloatArray]:
    """The path with a waypoint `END_REACH` along its first and its last segment, where the
    segment is longer than twice that (the same motion: module docstring)."""
    points = [np.asarray(p, dtype=float) for p in path]
    if len(points) < 2:
        return points
    first = distance_fn(points[0], points[1])
    if first > 2.0 * END_REACH:
        points.insert(1, interpolate_fn(points[0], points[1], END_REACH / first))
    last = distance_fn(points[-2], points[-1])
    if last > 2.0 * END_REACH:
        points.insert(-1, interpolate_fn(points[-1], points[-2], END_REACH / last))
    return points


@dataclass
class FinishedPath:
    """What the finishing pass made of a raw planner path."""

    path: FloatArray | None  # the certified path, or None
    message: str = ""
    stats: dict[str, float] = field(default_factory=dict)
    short: list[FloatArray] = field(default_factory=list)  # the shortcut path, whatever its verdict


def shortcut_and_certify(
    raw: Sequence[FloatArray],
    *,
    segment_free_fn: SegmentFn,
    distance_fn: DistanceFn,
    interpolate_fn: InterpolateFn,
    validate_fn: ValidateFn,
    budget_s: float,
    rng: np.random.Generator,
    max_iters: int = 100,
) -> FinishedPath:
    """Shortcut within `budget_s`, then validate; fall back to the raw path if that fails."""
    began = time.perf_counter()
    short = shortcut(
        raw,
        segment_free_fn=segment_free_fn,
        distance_fn=distance_fn,
        interpolate_fn=interpolate_fn,
        budget_s=budget_s,
        rng=rng,
        max_iters=max_iters,
    )
    anchored = functools.partial(
        anchor_ends, distance_fn=distance_fn, interpolate_fn=interpolate_fn
    )
    short = anchored(short)
    shortcut_ms = (time.perf_counter() - began) * 1e3
    stats = {
        "shortcut_ms": shortcut_ms,
        "length_before": path_length(raw, distance_fn),
        "waypoints_before": float(len(raw)),
    }
    message = ""
    for candidate in (short, anchored(raw)):
        began = time.perf_counter()
        ok, why = validate_fn(np.asarray(candidate, dtype=float))
        stats["validate_ms"] = stats.get("validate_ms", 0.0) + (time.perf_counter() - began) * 1e3
        if ok:
            stats["length_after"] = path_length(candidate, distance_fn)
            stats["waypoints_after"] = float(len(candidate))
            stats["shortcut_rejected"] = float(candidate is not short)
            return FinishedPath(np.asarray(candidate, dtype=float), "", stats, short)
        message = message or why
    why = f"the planner's path failed certified validation: {message}"
    return FinishedPath(None, why, stats, short)
