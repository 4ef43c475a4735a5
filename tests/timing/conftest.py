"""Timing fixtures: the reference robot's limits and a few small trajectories."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from trajcache.geometry.model.robot import RobotModel
from trajcache.reference.robot import reference_model
from trajcache.timing import KinematicLimits, kinematic_limits

SETTINGS = SimpleNamespace(
    timing_base_velocity=(0.5, 0.5, 1.0),
    timing_base_acceleration=(0.5, 0.5, 1.0),
    timing_base_jerk=(2.0, 2.0, 4.0),
    timing_joint_acceleration=5.0,
    timing_joint_jerk=50.0,
)


@pytest.fixture(scope="session")
def model() -> RobotModel:
    """The reference robot (planar base + 7 joints)."""
    return reference_model()


@pytest.fixture(scope="session")
def limits(model: RobotModel) -> KinematicLimits:
    """Its limits with the test settings."""
    return kinematic_limits(model, SETTINGS)


def arm_move(*points: list[float]) -> np.ndarray:
    """States of an arm motion with the base still at (1, 2, 0.5)."""
    return np.array([[1.0, 2.0, 0.5, *p] for p in points], dtype=float)


@pytest.fixture
def corner_path() -> np.ndarray:
    """Three key states with a sharp corner at the middle one."""
    return arm_move(
        [0.0, -0.5, 0.0, 0.8, 0.0, 1.0, 0.0],
        [0.9, -0.2, 0.3, 1.2, 0.1, 1.3, 0.2],
        [0.2, 0.3, -0.2, 1.6, -0.4, 0.9, 0.5],
    )
