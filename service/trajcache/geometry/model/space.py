"""The state space of a robot: the one place for angle wrapping, state differences, path length
and whether the base stays still.

A state is (x, y, θ, q1 … qn) for a planar base, (q1 … qn) for a fixed one. θ is an angle (SO(2)):
differences wrap it into [−π, π), so they take the short way round. The planners
(`planning/space.py`, `planning/motion.py`), the cache (`cache/metric.py`, `cache/adapt.py`),
validation and the quality measures all call these functions instead of writing the wrap again.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray

TWO_PI = 2.0 * math.pi
THETA = 2  # index of the base heading in a planar state
# How far apart (m, rad) a planar base's start and goal may be and still count as one pose. The
# planners once allowed 1e-6 and the cache's adaptation 1e-9; both now use the stricter 1e-9, so a
# base that moves at all is never held in place (a held base ends where it started, not at the
# requested goal).
BASE_STILL_TOLERANCE = 1e-9


def wrap_angle(a: npt.ArrayLike) -> FloatArray:
    """Angles (radians, any shape) wrapped to [−π, π)."""
    wrapped = np.mod(np.asarray(a, dtype=np.float64) + np.pi, TWO_PI) - np.pi
    # np.mod may round a tiny negative remainder up to exactly 2π, which would give +π.
    return np.where(wrapped >= np.pi, wrapped - TWO_PI, wrapped)


def state_steps(starts: npt.ArrayLike, ends: npt.ArrayLike, *, base: BaseType) -> FloatArray:
    """ends − starts (states, or batches of them), the base angle taking the short way."""
    delta = np.asarray(ends, dtype=float) - np.asarray(starts, dtype=float)
    if base is BaseType.PLANAR:
        delta[..., THETA] = wrap_angle(delta[..., THETA])
    return delta


def segment_deltas(states: npt.ArrayLike, *, base: BaseType) -> FloatArray:
    """Differences (N − 1, D) between consecutive states, the base angle taking the short way."""
    array = np.asarray(states, dtype=float)
    return state_steps(array[:-1], array[1:], base=base)


def path_length(states: npt.ArrayLike, *, base: BaseType) -> float:
    """State-space length: Σ of Euclidean segment lengths, the base angle taking the short way."""
    array = np.asarray(states, dtype=float)
    if len(array) < 2:
        return 0.0
    return float(np.linalg.norm(segment_deltas(array, base=base), axis=1).sum())


def base_is_still(start: npt.ArrayLike, goal: npt.ArrayLike, base: BaseType) -> bool:
    """True when a planar base has the same pose (within `BASE_STILL_TOLERANCE`) at both ends;
    always False for a fixed base."""
    if base is not BaseType.PLANAR:
        return False
    delta = np.abs(state_steps(np.asarray(start)[:3], np.asarray(goal)[:3], base=base))
    return bool(np.all(delta <= BASE_STILL_TOLERANCE))


def compiled_input(values: npt.ArrayLike) -> FloatArray:
    """`values` as the compiled kernels are warmed for: float64, C-ordered and writable. numba
    types a read-only array apart and would compile the kernel again, on a request, for it (the
    index's cached key states are read-only); such an array is copied, any other passed as is."""
    array = np.asarray(values, dtype=np.float64)
    if array.flags.c_contiguous and array.flags.writeable:
        return array
    return np.array(array, dtype=np.float64, order="C")
