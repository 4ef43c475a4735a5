"""Kinematic limits of a model for timing: velocity from the URDF, the rest from configuration."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray


class TimingSettings(Protocol):
    """The part of the service settings that timing reads (documented in core/config.py)."""

    @property
    def timing_base_velocity(self) -> Sequence[float]: ...
    @property
    def timing_base_acceleration(self) -> Sequence[float]: ...
    @property
    def timing_base_jerk(self) -> Sequence[float]: ...
    @property
    def timing_joint_acceleration(self) -> float: ...
    @property
    def timing_joint_jerk(self) -> float: ...


@dataclass(frozen=True)
class KinematicLimits:
    """Bounds on |velocity|, |acceleration| and |jerk| per state value (all finite, > 0)."""

    velocity: FloatArray
    acceleration: FloatArray
    jerk: FloatArray


def _configured(values: FloatArray | None, default: float, count: int) -> FloatArray:
    """Per-joint configured values, NaN (or no configuration) replaced by the default."""
    if values is None:
        return np.full(count, float(default))
    out = np.asarray(values, dtype=float).copy()
    out[~np.isfinite(out)] = float(default)
    return out


def _scaling(value: float, name: str) -> float:
    if not (np.isfinite(value) and 0.0 < value <= 1.0):
        raise ValueError(f"{name} must be in (0, 1], got {value}")
    return float(value)


def kinematic_limits(
    model: RobotModel,
    settings: TimingSettings,
    *,
    velocity_scaling: float = 1.0,
    acceleration_scaling: float = 1.0,
) -> KinematicLimits:
    """The model's limits per state value, scaled; jerk scales with the acceleration factor.

    Arm joints: velocity from the URDF, acceleration and jerk from the model's configuration
    (given at registration) or the settings' defaults. Planar base (x, y, θ): from the settings.
    """
    vs = _scaling(velocity_scaling, "velocity_scaling")
    acs = _scaling(acceleration_scaling, "acceleration_scaling")
    arm = len(model.joint_names)
    velocity = np.asarray(model.velocity_limits, dtype=float)[model.arm_offset :]
    acceleration = _configured(model.acceleration_limits, settings.timing_joint_acceleration, arm)
    jerk = _configured(model.jerk_limits, settings.timing_joint_jerk, arm)
    if model.base is BaseType.PLANAR:
        velocity = np.concatenate([np.asarray(settings.timing_base_velocity, float), velocity])
        acceleration = np.concatenate(
            [np.asarray(settings.timing_base_acceleration, float), acceleration]
        )
        jerk = np.concatenate([np.asarray(settings.timing_base_jerk, float), jerk])
    for name, values in (("velocity", velocity), ("acceleration", acceleration), ("jerk", jerk)):
        if values.shape != (model.dof,) or not np.all(np.isfinite(values) & (values > 0)):
            raise ValueError(f"{name} limits must be {model.dof} finite values > 0: {values}")
    return KinematicLimits(velocity * vs, acceleration * acs, jerk * acs)
