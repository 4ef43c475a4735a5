"""Which start-goal pairs are near a request's, compiled: the relevance test of `cache.index`.

A key is a start and a goal state side by side (2·D values). `cache.index.TrajectoryIndex.query`
hands this the rows to test (the delta buffer whole, the KD-tree's
candidates of the main block) and both orientations of the query at once. For each row and
orientation it applies the paper's metric (`cache.metric.state_distance`) to both ends:
d_base = ‖Δp‖ + |wrap(Δθ)| (0 for a fixed base, or when only the arm is matched) and
d_arm = max |ΔJ|; a row is relevant when d_base < t and d_arm < t at both ends. It returns the
relevant ones with their start and goal distances (d_base + d_arm, the request's start first),
so the index ranks a handful of rows in Python instead of every candidate in numpy calls.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from trajcache.geometry.model.space import TWO_PI

__all__ = ["relevant_rows"]

_PI = math.pi


@numba.njit(cache=True, nogil=True)
def relevant_rows(keys, rows, queries, threshold, planar, arm_only):  # type: ignore[no-untyped-def]  # pragma: no cover
    """For each of `rows` (indices into `keys` (n, 2D)) and each query of `queries` (2, 2D:
    forward, then start and goal swapped), whether both ends are within `threshold` (module
    docstring). Returns (K,) row positions in `rows`, orientations (1: reversed), the distance
    of the request's start and of its goal, for the relevant (row, orientation) pairs, forward
    ones first."""
    dim = keys.shape[1] // 2
    arm_from = 3 if planar else 0
    n = rows.shape[0]
    found = np.empty(2 * n, dtype=np.int64)
    reverse = np.empty(2 * n, dtype=np.int64)
    near_start = np.empty(2 * n)
    near_goal = np.empty(2 * n)
    count = 0
    for rev in range(2):
        for k in range(n):
            key = keys[rows[k]]
            first_end = second_end = 0.0
            relevant = True
            for end in range(2):
                at = end * dim
                arm = 0.0
                for j in range(at + arm_from, at + dim):  # most rows fail on their first value
                    gap = abs(queries[rev, j] - key[j])
                    if not gap < threshold:
                        relevant = False
                        break
                    arm = max(arm, gap)
                if not relevant:
                    break
                base = 0.0
                if planar and not arm_only:
                    dx, dy = queries[rev, at] - key[at], queries[rev, at + 1] - key[at + 1]
                    turn = (queries[rev, at + 2] - key[at + 2] + _PI) % TWO_PI - _PI
                    if turn >= _PI:  # as `wrap_angle`: a remainder rounded up to 2π
                        turn -= TWO_PI
                    base = math.hypot(dx, dy) + abs(turn)
                if not (base < threshold and arm < threshold):
                    relevant = False
                    break
                if end == 0:
                    first_end = base + arm
                else:
                    second_end = base + arm
            if relevant:
                found[count], reverse[count] = k, rev
                near_start[count] = second_end if rev else first_end
                near_goal[count] = first_end if rev else second_end
                count += 1
    return found[:count], reverse[:count], near_start[:count], near_goal[:count]
