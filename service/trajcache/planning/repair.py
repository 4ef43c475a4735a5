"""Repairing a path whose segments fail certification, segment by segment.

Certified validation can reject a segment that the planner's sample checks passed: between two
samples it passes closer to something than the distance bounds can prove free, or it touches a
thin obstacle. `repair_path` keeps every segment `certify_fn` proves free and replaces each other
one by the waypoints `detour_fn` finds between its two ends, whose segments it certified (the
planners' detour is RRIS with the certified check as its segment check). Certifying a path
segment by segment proves what validating it does, as validation interpolates and certifies
each straight segment on its own.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from trajcache.geometry.model.shapes import FloatArray
from trajcache.planning.deadline import Deadline

SegmentFn = Callable[[FloatArray, FloatArray], bool]
DetourFn = Callable[[FloatArray, FloatArray], list[FloatArray] | None]


@dataclass
class Repair:
    """A repaired path (None: some segment found no certified detour) and what it took."""

    path: list[FloatArray] | None
    repaired: int  # segments replaced by a detour
    failed: int  # segments that found none (0 or 1: the repair stops at the first)


def repair_path(
    path: Sequence[FloatArray],
    *,
    certify_fn: SegmentFn,
    detour_fn: DetourFn,
    budget: Deadline,
) -> Repair:
    """`path` with each segment `certify_fn` rejects replaced by a `detour_fn` detour."""
    points = [np.asarray(p, dtype=float) for p in path]
    out, repaired = points[:1], 0
    for a, b in itertools.pairwise(points):
        if budget.expired():
            return Repair(None, repaired, 0)
        if certify_fn(a, b):
            out.append(b)
            continue
        detour = detour_fn(a, b)
        if detour is None:
            return Repair(None, repaired, 1)
        out.extend(np.asarray(p, dtype=float) for p in detour[1:])
        repaired += 1
    return Repair(out, repaired, 0)


def remembered(segment_fn: SegmentFn) -> SegmentFn:
    """`segment_fn` that answers a segment it was asked about before from memory."""
    verdicts: dict[bytes, bool] = {}

    def check(a: FloatArray, b: FloatArray) -> bool:
        key = np.asarray(a, dtype=float).tobytes() + np.asarray(b, dtype=float).tobytes()
        verdict = verdicts.get(key)
        if verdict is None:
            verdict = verdicts[key] = segment_fn(a, b)
        return verdict

    return check
