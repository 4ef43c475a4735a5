"""Timed trajectories: time-optimal (toppra) or jerk-limited (Ruckig) timing of key states.

What the timed path guarantees:

- `linear` path (and every `jerk_limited` timing): the time law follows the validated straight
  segments exactly and comes to rest where the direction changes, so it is exactly as safe as
  the trajectory it times.
- `spline` path: a natural cubic spline through every key state (no stops). Between key states
  it may bow out, so it is certified on its own: sampled so densely that every straight chord
  between samples stays within `CHORD_TOLERANCE_M` (0.1 mm) of the spline for every point of the
  robot, and that polyline is run through the certified validator (`certify_fn`). Without a
  certifier, or when certification fails, the `linear` path is used instead (`path` says which).

Limits: on straight segments the velocity and acceleration limits hold everywhere; along a
spline they are checked at four points per toppra grid interval and time is stretched until
they hold there. Times are seconds from the start; the base angle stays continuous.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import THETA, wrap_angle
from trajcache.timing._jerk import jerk_limited
from trajcache.timing._limits import KinematicLimits, TimingSettings, kinematic_limits
from trajcache.timing._paths import (
    PolylinePath,
    SplinePath,
    certification_positions,
    distinct,
    gridpoints,
    is_straight,
    path_positions,
    unwrap_states,
)
from trajcache.timing._toppra import time_optimal
from trajcache.timing._trajectory import (
    PathShape,
    Samples,
    TimedTrajectory,
    TimingError,
    TimingMethod,
    stationary,
)

__all__ = [
    "CHORD_TOLERANCE_M",
    "GRID_POINTS",
    "KinematicLimits",
    "PathShape",
    "Samples",
    "TimedTrajectory",
    "TimingError",
    "TimingMethod",
    "TimingSettings",
    "kinematic_limits",
    "time_trajectory",
]

CHORD_TOLERANCE_M = 1e-4  # how far the certified polyline may be from the spline, anywhere
GRID_POINTS = 16  # toppra gridpoints per trajectory (at least 2 per segment)
_CORNER_COS = 1.0 - 1e-12  # directions closer than this count as one straight line

CertifyFn = Callable[[FloatArray], bool]


def time_trajectory(
    states: FloatArray,
    *,
    base: BaseType,
    limits: KinematicLimits,
    method: TimingMethod = TimingMethod.TOPPRA,
    path: PathShape = PathShape.SPLINE,
    certify_fn: CertifyFn | None = None,
    motion_bound: FloatArray | None = None,
    grid_points: int = GRID_POINTS,
) -> TimedTrajectory:
    """Time the key states `states` (n, dof), at rest at both ends.

    `certify_fn` validates a dense polyline (key states, base angle wrapped) against the scene;
    `motion_bound` is the largest displacement of any robot point per unit of each state value
    (`link_motion_bounds(model).max(axis=0)`). Both are needed for the `spline` path.
    """
    if method is TimingMethod.NONE:
        raise ValueError("method 'none' asks for no timing")
    q = unwrap_states(np.asarray(states, dtype=float), base=base)
    if q.ndim != 2 or len(q) < 1 or q.shape[1] != len(limits.velocity):
        raise TimingError(f"states of shape {q.shape} do not match {len(limits.velocity)} limits")
    points, ss, index = distinct(q, path_positions(q, limits.velocity))
    if len(points) == 1:
        return stationary(q, method, PathShape.LINEAR)
    if method is TimingMethod.JERK_LIMITED:
        segments = jerk_limited(points, limits)
        return TimedTrajectory(
            method, PathShape.LINEAR, segments.duration, segments.starts[index], segments.evaluate
        )
    spline, revalidated = None, False
    wants_spline = path is PathShape.SPLINE and not is_straight(points)
    if wants_spline and certify_fn is not None and motion_bound is not None:
        candidate = SplinePath(ss, points)
        positions = certification_positions(candidate, motion_bound, CHORD_TOLERANCE_M)
        samples = candidate(positions)
        if base is BaseType.PLANAR:
            samples[:, THETA] = wrap_angle(samples[:, THETA])
        if certify_fn(samples):
            spline, revalidated = candidate, True
    return _time_optimal_or_rest_to_rest(
        points, ss, index, limits, method, spline, revalidated, grid_points
    )


def _time_optimal_or_rest_to_rest(
    points: FloatArray,
    ss: FloatArray,
    index: np.ndarray,
    limits: KinematicLimits,
    method: TimingMethod,
    spline: SplinePath | None,
    revalidated: bool,
    grid_points: int,
) -> TimedTrajectory:
    """toppra along the certified spline, else along the polyline (stopping at its corners);
    where toppra finds no profile on either (a rare uncontrollable instance), rest to rest
    along each segment, jerk-limited."""
    grid, at_point = gridpoints(ss, grid_points)
    profile = None
    if spline is not None:
        try:
            profile = time_optimal(spline, grid, limits, np.empty(0, dtype=np.int64))
            used = PathShape.SPLINE
        except TimingError:
            revalidated = False
    if profile is None:
        polyline = PolylinePath(ss, points)
        try:
            profile = time_optimal(polyline, grid, limits, at_point[1:-1][_corners(polyline)])
        except TimingError:
            segments = jerk_limited(points, limits)
            return TimedTrajectory(
                TimingMethod.JERK_LIMITED,
                PathShape.LINEAR,
                segments.duration,
                segments.starts[index],
                segments.evaluate,
            )
        used = PathShape.LINEAR
    return TimedTrajectory(
        method,
        used,
        profile.duration,
        profile.times_at(at_point[index]),
        profile.evaluate,
        revalidated=revalidated,
    )


def _corners(path: PolylinePath) -> np.ndarray:
    """For each interior waypoint, whether the direction changes there (the robot must stop)."""
    unit = path.slopes / np.linalg.norm(path.slopes, axis=1, keepdims=True)
    cosines = np.sum(unit[:-1] * unit[1:], axis=1)
    return np.asarray(cosines < _CORNER_COS)
