"""Geometric paths for toppra: the exact polyline, the spline and its certification sampling."""

from __future__ import annotations

import numpy as np
import pytest

from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.path_quality import motion_bound
from trajcache.timing._paths import (
    PolylinePath,
    SplinePath,
    VelocityConstraintWithStops,
    certification_positions,
    gridpoints,
    is_straight,
    path_positions,
)


def test_polyline_is_exact_with_right_hand_derivatives() -> None:
    ss = np.array([0.0, 1.0, 3.0])
    points = np.array([[0.0, 0.0], [1.0, 2.0], [3.0, 2.0]])
    path = PolylinePath(ss, points)
    np.testing.assert_allclose(path(np.array([0.5, 2.0])), [[0.5, 1.0], [2.0, 2.0]])
    np.testing.assert_allclose(path(1.0, 1), [1.0, 0.0])  # the segment to the right
    np.testing.assert_allclose(path(3.0, 1), [1.0, 0.0])  # the last segment at the end
    np.testing.assert_allclose(path(np.array([0.2, 2.5]), 2), 0.0)
    with pytest.raises(ValueError, match="order 3"):
        path(0.5, 3)


def test_gridpoints_hold_every_waypoint_with_two_intervals_per_segment() -> None:
    ss = np.array([0.0, 0.001, 1.0, 5.0])
    grid, at_point = gridpoints(ss, 16)
    np.testing.assert_allclose(grid[at_point], ss)
    assert np.all(np.diff(at_point) >= 2) and np.all(np.diff(grid) > 0)


def test_velocity_constraint_stops_at_the_given_gridpoints() -> None:
    ss = np.array([0.0, 1.0, 2.0])
    path = PolylinePath(ss, np.array([[0.0], [1.0], [3.0]]))
    grid = np.linspace(0.0, 2.0, 5)
    constraint = VelocityConstraintWithStops(np.array([2.0]), np.array([2]))
    *_, xbound = constraint.compute_constraint_params(path, grid)
    assert xbound[2, 1] == 0.0 and xbound[1, 1] == pytest.approx(4.0)  # (v / |q'|)² = 4


def test_certification_chords_stay_within_tolerance(model: RobotModel) -> None:
    rng = np.random.default_rng(5)
    key = np.hstack([np.tile([1.0, 2.0, 0.5], (4, 1)), rng.uniform(-1, 1, (4, 7))])
    ss = path_positions(key, np.full(10, 3.14))
    spline = SplinePath(ss, key)
    bound = motion_bound(model)
    positions = certification_positions(spline, bound, 1e-4)
    assert set(ss) <= set(positions) and np.all(np.diff(positions) > 0)
    u = np.linspace(0, 1, 11)[1:-1]
    a, b = positions[:-1], positions[1:]
    inner = a[:, None] + u[None, :] * (b - a)[:, None]  # (chords, 9)
    curve = spline(inner.ravel()).reshape(len(a), len(u), -1)
    chord = spline(a)[:, None] + u[None, :, None] * (spline(b) - spline(a))[:, None]
    worst = np.max(np.abs(curve - chord) @ bound)
    assert worst <= 1e-4 * (1 + 1e-6)
    assert len(certification_positions(spline, bound, 1e-2)) < len(positions)


def test_is_straight() -> None:
    line = np.array([[0.0, 0.0], [1.0, 1.0], [3.0, 3.0]])
    assert is_straight(line)
    assert not is_straight(line[[0, 2, 1]])  # goes back along the line
    assert not is_straight(np.array([[0.0, 0.0], [1.0, 1.1], [3.0, 3.0]]))
