"""Cutting the segments that the bound levels leave open, before exact distances.

A straight segment is the union of its k equal pieces, so certifying each piece certifies the
segment: cutting changes where certification samples, never what it proves (`certify.py`). A
piece moves a k-th as far, so the bound levels (compiled, cheap) settle most of the pairs that
the whole segment leaves to exact distances (coal) and conservative advancement (Python).
Only segments with a pair left open are cut, once, so a path whose every pair the levels settle
pays nothing. What the pieces leave open goes to exact distances and advancement, as before.

Pieces are certified for the pairs left open on their segments alone (`restricted`: the union
over a run of segments; the scene's others count as allowed, the robot's others go unchecked). A
pair the levels settled on a segment is certified on the whole segment, so on each of its
pieces: checking it again on them would prove nothing new.

A finding in a piece is mapped back to its segment: piece i·k + j at fraction f is segment i at
fraction (j + f) / k, the same state (the pieces are the segment's own linear interpolation).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.validation.segments import Finding, OpenPairs, SegmentStatus

__all__ = ["PIECES", "certify_in_pieces", "restricted"]

PIECES = 4  # pieces an open segment is cut into (bench/certify_sampling.py measures the choice)


def open_runs(groups: list[OpenPairs]) -> list[tuple[int, int]]:
    """The runs (first, last) of consecutive segments that have a pair left open, in order."""
    runs: list[tuple[int, int]] = []
    for k in sorted({k for g in groups for k in g.rows[:, 0].tolist()}):  # few: Python is quicker
        if runs and k == runs[-1][1] + 1:
            runs[-1] = (runs[-1][0], k)
        else:
            runs.append((k, k))
    return runs


def pieces(states: FloatArray, delta: FloatArray, run: tuple[int, int], k: int) -> FloatArray:
    """The states of segments first..last cut into k pieces each, their own ends kept exactly;
    `delta` are the segments' differences (the base angle the short way)."""
    first, last = run
    frac = np.arange(k) / k
    cut = states[first : last + 1, None, :] + frac[None, :, None] * delta[first : last + 1, None]
    return np.vstack([cut.reshape(-1, states.shape[1]), states[last + 1 : last + 2]])


def certify_in_pieces(
    certify: Callable[[FloatArray], Finding],
    states: FloatArray,
    delta: FloatArray,
    groups: list[OpenPairs],
    k: int = PIECES,
) -> Finding:
    """Certify the open segments of `states` cut into k pieces (`certify` must not cut again);
    the earliest finding, mapped back to the segments of `states` (module docstring)."""
    probes = 0
    for run in open_runs(groups):
        found = certify(pieces(states, delta, run, k))
        probes += found.subdivisions
        if found.status is not SegmentStatus.FREE:  # runs are in order: it is the earliest
            segment, piece = divmod(found.segment, k)
            return Finding(
                found.status, run[0] + segment, (piece + found.at) / k, found.contacts, probes
            )
    return Finding(SegmentStatus.FREE, subdivisions=probes)


def restricted(
    groups: list[OpenPairs],
    allowed: NDArray[np.bool_],
    shape: tuple[int, int],
    pairs: tuple[NDArray[np.generic], ...],
) -> tuple[NDArray[np.bool_], tuple[NDArray[np.generic], ...], NDArray[np.int64]]:
    """The compiled levels' arguments for pieces of segments whose open pairs are `groups`
    (scene, robot): the allowed (element, object) matrix of `shape` with every pair but the
    open ones allowed too (`allowed` may be empty: none), the robot pairs as the kernels take
    them (`CollisionChecker.kernel_pairs`: the pair axis first in the first three arrays, last
    in the others) kept to the open ones, and the kept pairs' indices among all of them."""
    scene, robot = groups
    only = np.ones(shape, dtype=bool)
    only[scene.rows[:, 1], scene.rows[:, 2]] = False
    if allowed.shape[0]:
        only |= allowed
    ids = np.unique(robot.rows[:, 1])
    kept = tuple(
        np.ascontiguousarray(p[..., ids] if k >= 3 else p[ids]) for k, p in enumerate(pairs)
    )
    return only, kept, ids
