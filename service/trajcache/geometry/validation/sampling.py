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


def sample_counts(key_states: FloatArray, model: RobotModel, resolution: Resolution) -> IntArray:
    """Steps each segment between consecutive key states is cut into (at least 1 each)."""
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
    return np.maximum(np.ceil(steps - 1e-9).astype(np.int64), 1)


def interpolate(key_states: FloatArray, model: RobotModel, resolution: Resolution) -> FloatArray:
    """Dense samples along the straight segments between key states, key states included."""
    key = np.asarray(key_states, dtype=float)
    if len(key) < 2:
        return key.copy()
    delta = segment_deltas(key, base=model.base)
    counts = sample_counts(key, model, resolution)
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
