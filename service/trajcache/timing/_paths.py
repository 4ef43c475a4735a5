"""Geometric paths through key states for toppra: straight segments, or a cubic spline.

Both are parameterized by s = cumulative Σ‖Δq / v_max‖ (about the time each stretch takes at
full speed), so base metres and joint radians weigh alike. The straight path is exactly the
validated trajectory; the spline passes through every key state and may bow out between them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline
from toppra.constraint import (
    DiscretizationType,
    JointAccelerationConstraint,
    JointVelocityConstraint,
)
from toppra.constraint.linear_constraint import LinearConstraint
from toppra.interpolator import AbstractGeometricPath

from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import THETA

_SAME = 1e-12  # key states closer than this (in s) are one waypoint


def unwrap_states(states: FloatArray, *, base: BaseType) -> FloatArray:
    """A copy of `states` with the base angle made continuous (each step the short way)."""
    out = np.array(states, dtype=float, copy=True)
    if base is BaseType.PLANAR and len(out):
        out[:, THETA] = np.unwrap(out[:, THETA])
    return out


def path_positions(states: FloatArray, velocity: FloatArray) -> FloatArray:
    """Path parameter s of each key state: cumulative velocity-normalized distance."""
    steps = np.linalg.norm(np.diff(states, axis=0) / velocity, axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


def distinct(states: FloatArray, ss: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Drop repeated key states; also return, per original state, its index among those kept."""
    keep = np.concatenate([[True], np.diff(ss) > _SAME])
    return states[keep], ss[keep], np.cumsum(keep) - 1


class PolylinePath(AbstractGeometricPath):
    """Straight segments between waypoints; derivatives are those of the segment to the right."""

    def __init__(self, ss: FloatArray, points: FloatArray) -> None:
        self.ss = np.asarray(ss, dtype=float)
        self.points = np.asarray(points, dtype=float)
        self.slopes = np.diff(self.points, axis=0) / np.diff(self.ss)[:, None]

    def __call__(self, path_positions: Any, order: int = 0) -> FloatArray:
        s = np.asarray(path_positions, dtype=float)
        flat = np.atleast_1d(s)
        seg = np.clip(np.searchsorted(self.ss, flat, side="right") - 1, 0, len(self.slopes) - 1)
        if order == 0:
            out = self.points[seg] + (flat - self.ss[seg])[:, None] * self.slopes[seg]
        elif order == 1:
            out = self.slopes[seg]
        elif order == 2:
            out = np.zeros((len(flat), self.dof))
        else:
            raise ValueError(f"path derivative of order {order} is not available")
        return out[0] if s.ndim == 0 else out

    @property
    def dof(self) -> int:
        return int(self.points.shape[1])

    @property
    def path_interval(self) -> FloatArray:
        return np.array([self.ss[0], self.ss[-1]])

    @property
    def waypoints(self) -> FloatArray:
        return self.points


class SplinePath(AbstractGeometricPath):
    """A natural cubic spline through the waypoints (C², straight for two waypoints)."""

    def __init__(self, ss: FloatArray, points: FloatArray) -> None:
        self.ss = np.asarray(ss, dtype=float)
        self.points = np.asarray(points, dtype=float)
        self.spline = CubicSpline(self.ss, self.points, bc_type="natural")
        self._derivatives = [self.spline, self.spline.derivative(1), self.spline.derivative(2)]

    def __call__(self, path_positions: Any, order: int = 0) -> FloatArray:
        if order not in (0, 1, 2):
            raise ValueError(f"path derivative of order {order} is not available")
        out: FloatArray = self._derivatives[order](path_positions)
        return out

    @property
    def dof(self) -> int:
        return int(self.points.shape[1])

    @property
    def path_interval(self) -> FloatArray:
        return np.array([self.ss[0], self.ss[-1]])

    @property
    def waypoints(self) -> FloatArray:
        return self.points


# toppra's joint constraints format every limit into a description string when built (about
# 1 ms per timing); these build the same constraints from limits already checked (finite, > 0).


class VelocityConstraintWithStops(JointVelocityConstraint):
    """Joint velocity limits, and a full stop (ṡ = 0) at the given gridpoint indices."""

    def __init__(self, vlim: FloatArray, stops: FloatArray) -> None:
        LinearConstraint.__init__(self)
        self.vlim = np.stack([-vlim, vlim], axis=1).astype(float)
        self.dof = len(vlim)
        self._format_string = "    Velocity limit (with stops)\n"
        self.stops = np.asarray(stops, dtype=np.int64)

    def compute_constraint_params(self, path: Any, gridpoints: FloatArray) -> Any:
        *params, xbound = super().compute_constraint_params(path, gridpoints)
        xbound[self.stops] = 0.0
        return (*params, xbound)


class AccelerationConstraint(JointAccelerationConstraint):
    """Joint acceleration limits (toppra's, interpolation discretization)."""

    def __init__(self, alim: FloatArray) -> None:
        LinearConstraint.__init__(self)
        self.alim = np.stack([-alim, alim], axis=1).astype(float)
        self.dof = len(alim)
        self.set_discretization_type(DiscretizationType.Interpolation)
        self._format_string = "    Acceleration limit\n"
        self.identical = True


def gridpoints(ss: FloatArray, count: int) -> tuple[FloatArray, FloatArray]:
    """About `count` gridpoints spread by length, every waypoint one of them (≥ 2 intervals per
    segment); also return the gridpoint index of each waypoint."""
    lengths = np.diff(ss)
    per = np.maximum(np.ceil(lengths / lengths.sum() * count).astype(np.int64), 2)
    starts = np.concatenate([[0], np.cumsum(per)])
    seg = np.repeat(np.arange(len(lengths)), per)
    frac = (np.arange(starts[-1]) - starts[seg]) / per[seg]
    grid = np.concatenate([ss[seg] + frac * lengths[seg], ss[-1:]])
    return grid, starts


def certification_positions(
    path: SplinePath, motion_bound: FloatArray, tolerance_m: float
) -> FloatArray:
    """Path positions whose straight chords stay within `tolerance_m` of the spline in space.

    On a cubic piece q'' is linear, so |q''| peaks at the piece's ends; a chord of length h in s
    then deviates from the spline by at most |q''|·h²/8 per coordinate, and no point of the robot
    by more than Σ_d motion_bound[d]·|q''_d|·h²/8 (`link_motion_bounds`, maximum over links).
    """
    ss = path.ss
    curvature = np.abs(path(ss, 2))
    peak = np.maximum(curvature[:-1], curvature[1:]) @ motion_bound  # per piece
    lengths = np.diff(ss)
    with np.errstate(divide="ignore"):
        h = np.where(peak > 0, np.sqrt(8.0 * tolerance_m / np.maximum(peak, 1e-300)), np.inf)
    per = np.maximum(np.ceil(lengths / h), 1).astype(np.int64)
    parts = [
        np.linspace(a, b, n, endpoint=False)
        for a, b, n in zip(ss[:-1], ss[1:], per.tolist(), strict=True)
    ]
    return np.concatenate([*parts, ss[-1:]]) if parts else ss.copy()


def is_straight(points: FloatArray) -> bool:
    """True when every waypoint lies on the line through the first and the last."""
    if len(points) <= 2:
        return True
    direction = points[-1] - points[0]
    norm = float(np.linalg.norm(direction))
    if norm == 0.0:
        return False
    rel = points - points[0]
    along = rel @ direction / norm**2
    off = rel - along[:, None] * direction
    return bool(np.all(np.linalg.norm(off, axis=1) <= 1e-9 * max(1.0, norm))) and bool(
        np.all(np.diff(along) >= 0)
    )
