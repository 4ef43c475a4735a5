"""Jerk-limited timing with Ruckig: jerk, acceleration and velocity limits; straight segments."""

from __future__ import annotations

import numpy as np

from tests.timing.conftest import arm_move
from trajcache.geometry.model.robot import BaseType
from trajcache.timing import KinematicLimits, PathShape, TimingMethod, time_trajectory


def test_jerk_limited_motion_respects_all_limits_and_rests_at_key_states(
    limits: KinematicLimits, corner_path: np.ndarray
) -> None:
    timed = time_trajectory(
        corner_path, base=BaseType.PLANAR, limits=limits, method=TimingMethod.JERK_LIMITED
    )
    assert timed.method is TimingMethod.JERK_LIMITED and timed.path is PathShape.LINEAR
    period = 1e-3
    s = timed.sample(period)
    assert np.max(np.abs(s.velocities) / limits.velocity) <= 1 + 1e-6
    assert np.max(np.abs(s.accelerations) / limits.acceleration) <= 1 + 1e-6
    jerk = np.abs(np.diff(s.accelerations, axis=0)) / np.diff(s.times)[:, None]
    assert np.max(jerk / limits.jerk) <= 1 + 1e-3
    keys = timed.sample()
    np.testing.assert_allclose(keys.positions, corner_path, atol=1e-9)
    np.testing.assert_allclose(keys.velocities, 0.0, atol=1e-9)
    np.testing.assert_allclose(keys.accelerations, 0.0, atol=1e-9)
    # phase-synchronized: every sample on the straight segment between its key states
    for k in range(len(corner_path) - 1):
        inside = (s.times >= timed.waypoint_times[k]) & (s.times <= timed.waypoint_times[k + 1])
        a, b = corner_path[k], corner_path[k + 1]
        lam = (s.positions[inside] - a) @ (b - a) / ((b - a) @ (b - a))
        off = s.positions[inside] - (a + lam[:, None] * (b - a))
        assert np.max(np.abs(off)) < 1e-9 and lam.min() > -1e-9 and lam.max() < 1 + 1e-9


def test_jerk_limited_is_never_faster_than_time_optimal(limits: KinematicLimits) -> None:
    states = arm_move([0, -0.5, 0, 0.8, 0, 1.0, 0], [0.8, 0.2, -0.3, 1.4, 0.5, 1.5, 0.9])
    jerk = time_trajectory(
        states, base=BaseType.PLANAR, limits=limits, method=TimingMethod.JERK_LIMITED
    )
    optimal = time_trajectory(states, base=BaseType.PLANAR, limits=limits, path=PathShape.LINEAR)
    assert optimal.duration <= jerk.duration < 1.5 * optimal.duration
