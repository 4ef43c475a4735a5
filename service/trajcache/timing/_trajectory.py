"""A timed trajectory: a time law along a path, evaluated and sampled for the controller."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

import numpy as np

from trajcache.geometry.model.shapes import FloatArray

EvaluateFn = Callable[[FloatArray], tuple[FloatArray, FloatArray, FloatArray]]


class TimingMethod(str, Enum):
    """How a trajectory is timed."""

    TOPPRA = "toppra"  # time-optimal under velocity and acceleration limits (TOPP-RA)
    JERK_LIMITED = "jerk_limited"  # rest-to-rest S-curves per segment (Ruckig), jerk-bounded
    NONE = "none"  # not timed


class PathShape(str, Enum):
    """The geometric path the time law follows."""

    SPLINE = "spline"  # cubic spline through every key state, re-validated; no stops
    LINEAR = "linear"  # the validated straight segments exactly; stops at every key state


class TimingError(ValueError):
    """The trajectory could not be timed (a degenerate path or a solver failure)."""


@dataclass(frozen=True)
class Samples:
    """Sampled points: times (s from start), positions, velocities, accelerations."""

    times: FloatArray  # (n,)
    positions: FloatArray  # (n, dof)
    velocities: FloatArray
    accelerations: FloatArray


@dataclass(frozen=True)
class TimedTrajectory:
    """A trajectory with a time law; `evaluate_fn` maps times in [0, duration] to (q, q̇, q̈).

    Positions keep the base angle continuous (unwrapped from the first key state's angle).
    """

    method: TimingMethod
    path: PathShape
    duration: float
    waypoint_times: FloatArray  # when each key state (input order) is passed
    evaluate_fn: EvaluateFn
    revalidated: bool = False  # the spline was certified against the scene

    def evaluate(self, times: FloatArray) -> Samples:
        """Positions, velocities and accelerations at `times` (clipped to [0, duration])."""
        t = np.clip(np.asarray(times, dtype=float), 0.0, self.duration)
        q, qd, qdd = self.evaluate_fn(t)
        return Samples(t, q, qd, qdd)

    def sample(self, period_s: float | None = None, *, max_points: int = 10_000) -> Samples:
        """Points every `period_s` seconds (plus the end), or at the key states when None."""
        if period_s is None:
            return self.evaluate(self.waypoint_times)
        if not (np.isfinite(period_s) and period_s > 0):
            raise TimingError(f"sample_period_s must be > 0, got {period_s}")
        count = int(np.floor(self.duration / period_s + 1e-9)) + 1
        if count + 1 > max_points:
            raise TimingError(
                f"sample_period_s={period_s} gives {count + 1} points over {self.duration:.3f} s, "
                f"more than the limit of {max_points}"
            )
        times: FloatArray = np.arange(count, dtype=float) * period_s
        if self.duration - times[-1] > 1e-9:
            times = np.append(times, self.duration)
        return self.evaluate(times)


def stationary(states: FloatArray, method: TimingMethod, path: PathShape) -> TimedTrajectory:
    """The timing of a trajectory that does not move: zero duration, at rest."""
    point = np.asarray(states[0], dtype=float)

    def evaluate_fn(t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        q = np.broadcast_to(point, (len(t), len(point))).copy()
        return q, np.zeros_like(q), np.zeros_like(q)

    return TimedTrajectory(method, path, 0.0, np.zeros(len(states)), evaluate_fn)
