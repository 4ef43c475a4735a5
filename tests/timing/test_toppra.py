"""Time-optimal timing with toppra: limits, waypoints, the exact straight path, the spline."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.timing.conftest import arm_move
from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.path_quality import motion_bound
from trajcache.timing import (
    KinematicLimits,
    PathShape,
    TimedTrajectory,
    TimingError,
    TimingMethod,
    time_trajectory,
)

TOL = 1e-6


def dense(timed: TimedTrajectory, count: int = 2001) -> tuple[np.ndarray, ...]:
    s = timed.evaluate(np.linspace(0.0, timed.duration, count))
    return s.times, s.positions, s.velocities, s.accelerations


def limit_ratios(timed: TimedTrajectory, limits: KinematicLimits) -> tuple[float, float]:
    _, _, v, a = dense(timed)
    return float(np.max(np.abs(v) / limits.velocity)), float(
        np.max(np.abs(a) / limits.acceleration)
    )


def on_polyline(timed: TimedTrajectory, states: np.ndarray) -> float:
    """Largest distance of a dense sample from the segment it should be on."""
    t, q, _, _ = dense(timed)
    worst = 0.0
    for k in range(len(states) - 1):
        inside = (t >= timed.waypoint_times[k]) & (t <= timed.waypoint_times[k + 1])
        a, b = states[k], states[k + 1]
        lam = np.clip((q[inside] - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        off = q[inside] - (a + lam[:, None] * (b - a))
        worst = max(worst, float(np.max(np.linalg.norm(off, axis=1), initial=0.0)))
    return worst


def straight_line_optimum(delta: np.ndarray, limits: KinematicLimits) -> float:
    """Minimum time of a rest-to-rest straight motion under box limits (trapezoid or triangle)."""
    moving = np.abs(delta) > 0
    v = float(np.min(limits.velocity[moving] / np.abs(delta[moving])))
    a = float(np.min(limits.acceleration[moving] / np.abs(delta[moving])))
    return 1.0 / v + v / a if v * v / a < 1.0 else 2.0 * np.sqrt(1.0 / a)


@pytest.mark.parametrize(
    "states",
    [
        arm_move([0, -0.5, 0, 0.8, 0, 1.0, 0], [0.8, 0.2, -0.3, 1.4, 0.5, 1.5, 0.9]),
        arm_move([0, 0, 0, 0, 0, 0, 0], [0.02, 0, 0, 0, 0, 0, 0]),  # short: never cruises
        np.array([[0.0, 0.0, 0.0, *[0.0] * 7], [2.0, 1.0, 1.5, *[0.0] * 7]]),  # base drive
    ],
)
def test_straight_motion_is_time_optimal_within_limits(
    model: RobotModel, limits: KinematicLimits, states: np.ndarray
) -> None:
    timed = time_trajectory(states, base=BaseType.PLANAR, limits=limits, path=PathShape.LINEAR)
    over_v, over_a = limit_ratios(timed, limits)
    assert over_v <= 1 + TOL and over_a <= 1 + TOL
    optimum = straight_line_optimum(states[1] - states[0], limits)
    assert optimum <= timed.duration <= optimum * 1.03


def test_timed_path_passes_every_key_state_at_rest_at_the_ends(
    limits: KinematicLimits, corner_path: np.ndarray
) -> None:
    for path in (PathShape.LINEAR, PathShape.SPLINE):
        timed = time_trajectory(
            corner_path,
            base=BaseType.PLANAR,
            limits=limits,
            path=path,
            certify_fn=lambda _: True,
            motion_bound=np.ones(10),
        )
        at_keys = timed.sample()
        np.testing.assert_allclose(at_keys.positions, corner_path, atol=1e-9)
        np.testing.assert_allclose(at_keys.times, timed.waypoint_times)
        assert at_keys.times[0] == 0.0 and at_keys.times[-1] == pytest.approx(timed.duration)
        np.testing.assert_allclose(at_keys.velocities[[0, -1]], 0.0, atol=1e-9)


def test_linear_path_follows_the_segments_exactly_and_stops_at_corners(
    limits: KinematicLimits, corner_path: np.ndarray
) -> None:
    timed = time_trajectory(corner_path, base=BaseType.PLANAR, limits=limits, path=PathShape.LINEAR)
    assert timed.path is PathShape.LINEAR and not timed.revalidated
    assert on_polyline(timed, corner_path) < 1e-9
    np.testing.assert_allclose(timed.sample().velocities[1], 0.0, atol=1e-9)
    over_v, over_a = limit_ratios(timed, limits)
    assert over_v <= 1 + TOL and over_a <= 1 + TOL


def test_collinear_key_states_do_not_stop_the_motion(limits: KinematicLimits) -> None:
    a, b = np.array([0, -0.5, 0, 0.8, 0, 1.0, 0.0]), np.array([1.2, 0.1, 0.6, 1.4, 0.3, 1.6, 0.9])
    states = arm_move(list(a), list(a + 0.4 * (b - a)), list(b))
    timed = time_trajectory(states, base=BaseType.PLANAR, limits=limits, path=PathShape.LINEAR)
    assert np.max(np.abs(timed.sample().velocities[1])) > 0.1
    optimum = straight_line_optimum(states[-1] - states[0], limits)
    assert optimum <= timed.duration <= optimum * 1.03


def test_certified_spline_is_faster_and_keeps_limits(
    model: RobotModel, limits: KinematicLimits
) -> None:
    corner_path = arm_move(
        [0.0, -0.5, 0.0, 0.8, 0.0, 1.0, 0.0],
        [0.6, -0.1, 0.3, 1.2, 0.2, 1.2, 0.3],
        [1.0, 0.5, 0.4, 1.3, 0.6, 1.1, 0.5],
    )
    seen: list[np.ndarray] = []

    def certify_fn(samples: np.ndarray) -> bool:
        seen.append(samples)
        return True

    spline = time_trajectory(
        corner_path,
        base=BaseType.PLANAR,
        limits=limits,
        certify_fn=certify_fn,
        motion_bound=motion_bound(model),
    )
    linear = time_trajectory(
        corner_path, base=BaseType.PLANAR, limits=limits, path=PathShape.LINEAR
    )
    assert spline.path is PathShape.SPLINE and spline.revalidated and len(seen) == 1
    assert spline.duration < 0.9 * linear.duration
    assert np.max(np.abs(spline.sample().velocities[1])) > 0.1  # no stop at the corner
    over_v, over_a = limit_ratios(spline, limits)
    assert over_v <= 1.01 and over_a <= 1.01
    # the certified polyline starts and ends at the key states and is dense
    np.testing.assert_allclose(seen[0][[0, -1]], corner_path[[0, -1]], atol=1e-12)
    assert len(seen[0]) > 20


def test_spline_falls_back_to_the_exact_path_when_not_certified(
    model: RobotModel, limits: KinematicLimits, corner_path: np.ndarray
) -> None:
    refused = time_trajectory(
        corner_path,
        base=BaseType.PLANAR,
        limits=limits,
        certify_fn=lambda _: False,
        motion_bound=motion_bound(model),
    )
    uncertified = time_trajectory(corner_path, base=BaseType.PLANAR, limits=limits)
    for timed in (refused, uncertified):
        assert timed.path is PathShape.LINEAR and not timed.revalidated
        assert on_polyline(timed, corner_path) < 1e-9


def test_base_angle_takes_the_short_way_and_stays_continuous(limits: KinematicLimits) -> None:
    states = np.array([[0.0, 0.0, 3.1, *[0.0] * 7], [0.0, 0.0, -3.1, *[0.0] * 7]])
    timed = time_trajectory(states, base=BaseType.PLANAR, limits=limits)
    _, q, _, _ = dense(timed)
    assert np.all(np.diff(q[:, 2]) >= -1e-12)  # turning one way, no jump
    end = timed.sample().positions[-1, 2]
    assert end == pytest.approx(-3.1 + 2 * np.pi)
    assert timed.duration < 1.0  # 0.083 rad, not 6.2


def test_repeated_and_identical_key_states(limits: KinematicLimits) -> None:
    a = [0.0, -0.5, 0.0, 0.8, 0.0, 1.0, 0.0]
    b = [0.5, -0.5, 0.0, 0.8, 0.0, 1.0, 0.0]
    timed = time_trajectory(arm_move(a, a, b, b), base=BaseType.PLANAR, limits=limits)
    assert timed.waypoint_times[0] == timed.waypoint_times[1] == 0.0
    assert timed.waypoint_times[2] == timed.waypoint_times[3] == pytest.approx(timed.duration)
    still = time_trajectory(arm_move(a, a), base=BaseType.PLANAR, limits=limits)
    assert still.duration == 0.0
    np.testing.assert_allclose(still.sample(0.1).velocities, 0.0)


def test_bad_calls_are_refused(limits: KinematicLimits, corner_path: np.ndarray) -> None:
    with pytest.raises(ValueError, match="none"):
        time_trajectory(corner_path, base=BaseType.PLANAR, limits=limits, method=TimingMethod.NONE)
    with pytest.raises(TimingError, match="do not match"):
        time_trajectory(corner_path[:, :5], base=BaseType.PLANAR, limits=limits)


def test_a_profile_with_nan_speeds_is_not_returned_a_jerk_limited_one_is(
    limits: KinematicLimits, corner_path: np.ndarray, monkeypatch: pytest.MonkeyPatch
) -> None:
    import toppra.algorithm

    real = toppra.algorithm.TOPPRA.compute_parameterization

    def with_a_nan(self: Any, *args: Any, **kwargs: Any) -> Any:
        sdd, sd, v = real(self, *args, **kwargs)
        sd = np.array(sd, dtype=float)
        sd[len(sd) // 2] = np.sqrt(-1.0)  # what toppra's reachability sweep yields, rarely
        return sdd, sd, v

    monkeypatch.setattr(toppra.algorithm.TOPPRA, "compute_parameterization", with_a_nan)
    timed = time_trajectory(corner_path, base=BaseType.PLANAR, limits=limits)
    # toppra failed on the spline and on the polyline: rest to rest along each segment instead
    assert timed.method is TimingMethod.JERK_LIMITED and timed.path is PathShape.LINEAR
    _, q, v, a = dense(timed)
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(v)) and np.all(np.isfinite(a))
    velocity, acceleration = limit_ratios(timed, limits)
    assert velocity <= 1.0 + TOL and acceleration <= 1.0 + TOL
    assert on_polyline(timed, corner_path) < 1e-6
