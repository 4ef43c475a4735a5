"""Where validation samples a trajectory: the paper's resolution and the straight segments
between key states, cut into steps no longer than it (`validator.py` checks the samples)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import segment_deltas

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
    counts = sample_counts(key, model, resolution, subdivision)
    if len(counts) == 1:  # one segment, the usual cached motion
        frac = np.arange(counts[0] + 1) / counts[0]
        out = key[0] + frac[:, None] * delta[0]
        out[-1] = key[-1]
        return np.asarray(out)
    seg = np.repeat(np.arange(len(delta)), counts)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    frac = (np.arange(counts.sum()) - np.repeat(starts, counts)) / np.repeat(counts, counts)
    dense = key[seg] + frac[:, None] * delta[seg]
    return np.vstack([dense, key[-1:]])
