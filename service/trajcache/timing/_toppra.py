"""Time-optimal timing along a path with TOPP-RA (toppra): the profile ṡ(s) and its evaluation.

toppra returns ṡ at gridpoints; between them s̈ is constant (toppra's `ParametrizeConstAccel`),
so s(t) is piecewise quadratic and positions lie exactly on the geometric path. On straight
segments q' is constant and q'' = 0, so limits that hold at the gridpoints hold everywhere; on a
spline they are checked at several points per interval and the time is stretched if needed.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from toppra.algorithm import TOPPRA
from toppra.algorithm.algorithm import ParameterizationReturnCode

from trajcache.geometry.model.shapes import FloatArray
from trajcache.timing._limits import KinematicLimits
from trajcache.timing._paths import (
    AccelerationConstraint,
    PolylinePath,
    SplinePath,
    VelocityConstraintWithStops,
)
from trajcache.timing._trajectory import TimingError

logging.getLogger("toppra").setLevel(logging.ERROR)  # it logs every solve at INFO

_CHECKS_PER_INTERVAL = 4


@dataclass(frozen=True)
class PathProfile:
    """A time law s(t) along `path`: ṡ at gridpoints, constant s̈ between, times stretched by
    `stretch` (≥ 1) so that the limits hold between gridpoints too."""

    path: PolylinePath | SplinePath
    grid: FloatArray
    sd: FloatArray
    ts: FloatArray  # time at each gridpoint before stretching
    us: FloatArray  # s̈ on each interval before stretching
    stretch: float = 1.0

    @property
    def duration(self) -> float:
        """Total time (s)."""
        return float(self.ts[-1] * self.stretch)

    def times_at(self, indices: FloatArray) -> FloatArray:
        """Times (s) at which the gridpoints `indices` are passed."""
        return self.ts[np.asarray(indices, dtype=np.int64)] * self.stretch

    def evaluate(self, times: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(q, q̇, q̈) at `times` (s, within [0, duration])."""
        k = self.stretch
        t = np.asarray(times, dtype=float) / k
        i = np.clip(np.searchsorted(self.ts, t, side="right") - 1, 0, len(self.us) - 1)
        dt = t - self.ts[i]
        s = np.clip(self.grid[i] + dt * self.sd[i] + 0.5 * dt**2 * self.us[i], 0, self.grid[-1])
        sd = np.maximum(self.sd[i] + dt * self.us[i], 0.0)
        d1 = self.path(s, 1)
        q = self.path(s, 0)
        qd = d1 * sd[:, None]
        qdd = self.path(s, 2) * (sd**2)[:, None] + d1 * self.us[i][:, None]
        return q, qd / k, qdd / k**2


def time_optimal(
    path: PolylinePath | SplinePath,
    grid: FloatArray,
    limits: KinematicLimits,
    stops: FloatArray,
) -> PathProfile:
    """The time-optimal rest-to-rest profile along `path`, at rest at gridpoints `stops` too."""
    velocity = VelocityConstraintWithStops(limits.velocity, stops)
    acceleration = AccelerationConstraint(limits.acceleration)
    instance = TOPPRA(
        [velocity, acceleration],
        path,
        gridpoints=grid,
        solver_wrapper="seidel",
        parametrizer="ParametrizeConstAccel",
    )
    with np.errstate(invalid="ignore"):  # a NaN speed it computes is refused just below
        _, sd_vec, _ = instance.compute_parameterization(0.0, 0.0)
    if instance.problem_data.return_code != ParameterizationReturnCode.Ok or sd_vec is None:
        raise TimingError(f"toppra found no parameterization: {instance.problem_data.return_code}")
    sd = np.maximum(np.asarray(sd_vec, dtype=float), 0.0)
    ds = np.diff(grid)
    speed = sd[:-1] + sd[1:]
    if np.any(speed <= 0) or not np.all(np.isfinite(sd)):
        raise TimingError("toppra's profile stops inside a segment")
    ts = np.concatenate([[0.0], np.cumsum(2.0 * ds / speed)])
    us = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)
    profile = PathProfile(path, np.asarray(grid, dtype=float), sd, ts, us)
    if isinstance(path, PolylinePath):
        return profile
    return _stretched(profile, limits)


def _stretched(profile: PathProfile, limits: KinematicLimits) -> PathProfile:
    """Slow the whole profile down just enough that the limits hold between gridpoints."""
    fractions = np.arange(_CHECKS_PER_INTERVAL) / _CHECKS_PER_INTERVAL
    dts = np.diff(profile.ts)
    times = (profile.ts[:-1, None] + fractions[None, :] * dts[:, None]).ravel()
    times = np.append(times, profile.ts[-1])
    _, qd, qdd = profile.evaluate(times)
    over_v = float(np.max(np.abs(qd) / limits.velocity))
    over_a = float(np.max(np.abs(qdd) / limits.acceleration))
    stretch = max(1.0, over_v, float(np.sqrt(over_a)))
    if stretch == 1.0:
        return profile
    return PathProfile(
        profile.path, profile.grid, profile.sd, profile.ts, profile.us, stretch * (1 + 1e-9)
    )
