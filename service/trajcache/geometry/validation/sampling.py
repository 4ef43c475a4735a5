"""Where validation samples a trajectory: the paper's resolution and the straight segments
between key states, cut into steps no longer than it (`validator.py` checks the samples)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import compiled_input, segment_deltas

IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class Resolution:
    """Largest interpolation step per kind of state value."""

    position_m: float = 0.04
    orientation_rad: float = 0.04
    joint_rad: float = 0.035


def sample_counts(
    key_states: FloatArray, model: RobotModel, resolution: Resolution, subdivision: int = 1
) -> IntArray:
    """Steps each segment between consecutive key states is cut into (at least 1 each); with
    `subdivision`, each of those steps is cut into as many again (the samples of the coarser
    cut are among them).

    Certified validation may subdivide (`validator.CERTIFY_SUBDIVISION`): it proves the motion
    between samples, so their spacing decides only its cost. Finer samples leave fewer pairs to
    exact distances and conservative advancement in Python, but cost more bound evaluations.
    On 70 of the MotionBenchMaker Panda's planned paths, in tight shelves and cages
    (`bench/certify_sampling.py`), a third of the step took a third less CPU time (whole paths
    3.6 against 5.5 ms at the median, a hit's two new end segments 0.92 against 1.40 ms); on
    the reference robot's open workload (`bench/validation.py --smoke`) it took more (1.74
    against 1.34 ms per trajectory, 1.16 against 0.69 ms per workload motion). So it stays 1;
    the certifier cuts instead only the segments its bound levels leave open (`refine.py`)."""
    key = np.asarray(key_states, dtype=float)
    planar = model.base is BaseType.PLANAR
    delta = segment_deltas(key, base=model.base)
    off = model.arm_offset
    steps = np.zeros(len(delta))
    if planar:
        steps = np.hypot(delta[:, 0], delta[:, 1]) / resolution.position_m
        steps = np.maximum(steps, np.abs(delta[:, 2]) / resolution.orientation_rad)
    if delta.shape[1] > off:
        steps = np.maximum(steps, np.abs(delta[:, off:]).max(axis=1) / resolution.joint_rad)
    return np.maximum(np.ceil(steps - 1e-9).astype(np.int64), 1) * subdivision


def interpolate(
    key_states: FloatArray, model: RobotModel, resolution: Resolution, subdivision: int = 1
) -> FloatArray:
    """Dense samples along the straight segments between key states, key states included
    (`sample_counts` for `subdivision`)."""
    key = np.asarray(key_states, dtype=float)
    if len(key) < 2:
        return key.copy()
    delta = segment_deltas(key, base=model.base)
    if len(delta) == 1:  # one segment, the usual cached motion: compiled, as below
        r = resolution
        planar = model.base is BaseType.PLANAR
        return _one_segment(
            compiled_input(key), delta[0], model.arm_offset, planar, float(r.position_m),
            float(r.orientation_rad), float(r.joint_rad), int(subdivision),
        )  # fmt: skip
    counts = sample_counts(key, model, resolution, subdivision)
    seg = np.repeat(np.arange(len(delta)), counts)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    frac = (np.arange(counts.sum()) - np.repeat(starts, counts)) / np.repeat(counts, counts)
    dense = key[seg] + frac[:, None] * delta[seg]
    return np.vstack([dense, key[-1:]])


@numba.njit(cache=True, nogil=True)
def _one_segment(key, delta, arm_from, planar, position_m, orientation_rad, joint_rad, subdivision):  # type: ignore[no-untyped-def]  # pragma: no cover
    """`interpolate` of two key states whose difference is `delta` (the base angle the short
    way): `sample_counts`' steps, then key[0] + (i / count)·delta, the last sample key[1]."""
    steps = 0.0
    if planar:
        steps = math.hypot(delta[0], delta[1]) / position_m
        steps = max(steps, abs(delta[2]) / orientation_rad)
    widest = 0.0
    for j in range(arm_from, delta.shape[0]):
        widest = max(widest, abs(delta[j]))
    if delta.shape[0] > arm_from:
        steps = max(steps, widest / joint_rad)
    count = max(math.ceil(steps - 1e-9), 1) * subdivision
    out = np.empty((count + 1, key.shape[1]))
    for i in range(count):
        frac = i / count
        for d in range(key.shape[1]):
            out[i, d] = key[0, d] + frac * delta[d]
    out[count] = key[1]
    return out


@numba.njit(cache=True, nogil=True)
def first_out_of_limits(samples, lower, upper, arm_from):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The first sample with an arm value more than 1e-9 outside [lower, upper]; −1 if none."""
    for i in range(samples.shape[0]):
        for j in range(arm_from, samples.shape[1]):
            value = samples[i, j]
            if value < lower[j] - 1e-9 or value > upper[j] + 1e-9:
                return i
    return -1
