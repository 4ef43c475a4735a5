"""Jerk-limited timing with Ruckig: one rest-to-rest S-curve per straight segment.

With phase synchronization every joint follows the same normalized profile, so each segment is
traversed exactly along its straight line; the robot comes to rest at every key state.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

from trajcache.geometry.model.shapes import FloatArray
from trajcache.timing._limits import KinematicLimits
from trajcache.timing._trajectory import TimingError


@dataclass(frozen=True)
class SegmentProfiles:
    """Ruckig trajectories of consecutive segments and the time each one starts."""

    segments: list[Trajectory]
    starts: FloatArray  # (n_segments + 1,): start times, then the total duration

    @property
    def duration(self) -> float:
        """Total time (s)."""
        return float(self.starts[-1])

    def evaluate(self, times: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(q, q̇, q̈) at `times` (s, within [0, duration])."""
        t = np.asarray(times, dtype=float)
        last = len(self.segments) - 1
        index = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, last)
        dof = self.segments[0].degrees_of_freedom
        out = np.empty((3, len(t), dof))
        for row, (k, time) in enumerate(zip(index.tolist(), t.tolist(), strict=True)):
            local = min(max(time - float(self.starts[k]), 0.0), self.segments[k].duration)
            out[:, row] = self.segments[k].at_time(local)
        return out[0], out[1], out[2]


def jerk_limited(points: FloatArray, limits: KinematicLimits) -> SegmentProfiles:
    """Rest-to-rest jerk-limited motions along each segment between consecutive `points`."""
    dof = points.shape[1]
    otg = Ruckig(dof)
    segments: list[Trajectory] = []
    for a, b in itertools.pairwise(points):
        inp = InputParameter(dof)
        inp.current_position = a.tolist()
        inp.target_position = b.tolist()
        inp.current_velocity = inp.current_acceleration = [0.0] * dof
        inp.target_velocity = inp.target_acceleration = [0.0] * dof
        inp.max_velocity = limits.velocity.tolist()
        inp.max_acceleration = limits.acceleration.tolist()
        inp.max_jerk = limits.jerk.tolist()
        inp.synchronization = Synchronization.Phase
        trajectory = Trajectory(dof)
        result = otg.calculate(inp, trajectory)
        if result not in (Result.Working, Result.Finished):
            raise TimingError(f"ruckig could not time a segment: {result}")
        segments.append(trajectory)
    durations = np.array([s.duration for s in segments], dtype=float)
    return SegmentProfiles(segments, np.concatenate([[0.0], np.cumsum(durations)]))
