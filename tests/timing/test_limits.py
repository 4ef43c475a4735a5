"""Kinematic limits: URDF velocities, configured or default accelerations, base from settings."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import ValidationError

from tests.timing.conftest import SETTINGS
from trajcache.core.config import Settings
from trajcache.geometry.model.robot import RobotModel
from trajcache.timing import kinematic_limits


def test_arm_velocity_from_urdf_base_and_defaults_from_settings(model: RobotModel) -> None:
    limits = kinematic_limits(model, SETTINGS)
    np.testing.assert_allclose(limits.velocity, [0.5, 0.5, 1.0, *[3.14] * 7])
    np.testing.assert_allclose(limits.acceleration, [0.5, 0.5, 1.0, *[5.0] * 7])
    np.testing.assert_allclose(limits.jerk, [2.0, 2.0, 4.0, *[50.0] * 7])


def test_configured_limits_override_defaults_joint_by_joint(model: RobotModel) -> None:
    accel = np.full(7, np.nan)
    accel[1] = 2.5
    configured = dataclasses.replace(model, acceleration_limits=accel, jerk_limits=np.full(7, 9.0))
    limits = kinematic_limits(configured, SETTINGS)
    assert limits.acceleration[4] == 2.5 and limits.acceleration[3] == 5.0
    np.testing.assert_allclose(limits.jerk[3:], 9.0)


def test_scaling_multiplies_velocity_and_acceleration_and_jerk(model: RobotModel) -> None:
    limits = kinematic_limits(model, SETTINGS, velocity_scaling=0.5, acceleration_scaling=0.25)
    np.testing.assert_allclose(limits.velocity[3:], 1.57)
    np.testing.assert_allclose(limits.acceleration[3:], 1.25)
    np.testing.assert_allclose(limits.jerk[3:], 12.5)


@pytest.mark.parametrize("value", [0.0, -0.5, 1.01, float("nan"), float("inf")])
def test_scaling_outside_zero_one_is_refused(model: RobotModel, value: float) -> None:
    with pytest.raises(ValueError, match="velocity_scaling"):
        kinematic_limits(model, SETTINGS, velocity_scaling=value)


def test_non_positive_settings_are_refused(model: RobotModel) -> None:
    bad = SimpleNamespace(**{**vars(SETTINGS), "timing_base_velocity": (0.5, 0.0, 1.0)})
    with pytest.raises(ValueError, match="velocity limits"):
        kinematic_limits(model, bad)


def test_base_limits_are_settings_read_as_json_lists(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TRAJCACHE_TIMING_BASE_VELOCITY", "[0.8, 0.4, 1.5]")
    assert Settings().timing_base_velocity == (0.8, 0.4, 1.5)
    with pytest.raises(ValidationError, match="three finite values > 0"):
        Settings(timing_base_acceleration=(0.5, -1.0, 1.0))
