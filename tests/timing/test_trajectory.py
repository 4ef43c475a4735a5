"""Sampling a timed trajectory for the controller."""

from __future__ import annotations

import numpy as np
import pytest

from tests.timing.conftest import arm_move
from trajcache.geometry.model.robot import BaseType
from trajcache.timing import KinematicLimits, TimedTrajectory, TimingError, time_trajectory


@pytest.fixture
def timed(limits: KinematicLimits) -> TimedTrajectory:
    states = arm_move([0, -0.5, 0, 0.8, 0, 1.0, 0], [0.8, 0.2, -0.3, 1.4, 0.5, 1.5, 0.9])
    return time_trajectory(states, base=BaseType.PLANAR, limits=limits)


def test_periodic_samples_end_exactly_at_the_duration(timed: TimedTrajectory) -> None:
    s = timed.sample(0.1)
    np.testing.assert_allclose(np.diff(s.times[:-1]), 0.1)
    assert s.times[0] == 0.0 and s.times[-1] == timed.duration
    assert 0 < s.times[-1] - s.times[-2] <= 0.1 + 1e-12
    assert s.positions.shape == s.velocities.shape == s.accelerations.shape == (len(s.times), 10)


def test_too_many_points_or_a_bad_period_is_refused(timed: TimedTrajectory) -> None:
    with pytest.raises(TimingError, match=r"sample_period_s=0\.0001"):
        timed.sample(0.0001, max_points=1000)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(TimingError, match="sample_period_s"):
            timed.sample(bad)


def test_evaluation_clips_to_the_trajectory(timed: TimedTrajectory) -> None:
    s = timed.evaluate(np.array([-1.0, timed.duration + 5.0]))
    np.testing.assert_allclose(s.velocities, 0.0, atol=1e-9)
    assert s.times[0] == 0.0 and s.times[1] == timed.duration
