"""A robot model's configuration for timing and quality, given when it is first registered.

Acceleration and jerk limits of the planning joints (one value for all, or by joint name;
joints left out use the service defaults) and the end-effector link. The configuration is not
part of the model's identity (the content hash) and cannot change after registration, so every
replica's cached model agrees with the stored one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from trajcache.geometry.model.robot import BASE_STATE_NAMES, RobotModel
from trajcache.services.errors import ConflictError, InvalidInputError

JointLimits = float | Mapping[str, float]  # one value for every planning joint, or per joint


@dataclass(frozen=True)
class ModelConfig:
    """A model's configuration as stored: limits per joint name (only those given), EE link."""

    acceleration_limits: dict[str, float] | None = None
    jerk_limits: dict[str, float] | None = None
    end_effector_link: str | None = None

    def apply(self, model: RobotModel) -> RobotModel:
        """`model` with this configuration (limits as arrays in joint order, NaN = default)."""

        def array(limits: dict[str, float] | None) -> np.ndarray | None:
            if limits is None:
                return None
            return np.array([limits.get(name, np.nan) for name in model.joint_names], dtype=float)

        return replace(
            model,
            acceleration_limits=array(self.acceleration_limits),
            jerk_limits=array(self.jerk_limits),
            end_effector_link=self.end_effector_link,
        )


def joint_limits(
    model: RobotModel, limits: JointLimits | None, what: str
) -> dict[str, float] | None:
    """Per-joint limits from one value or a mapping by planning joint name; InvalidInputError
    names a wrong joint or value."""
    if limits is None:
        return None
    if isinstance(limits, Mapping):
        given = dict(limits)
        unknown = sorted(set(given) - set(model.joint_names))
        if unknown:
            base = sorted(set(unknown) & set(BASE_STATE_NAMES))
            hint = " (base limits are service settings: TRAJCACHE_TIMING_BASE_*)" if base else ""
            raise InvalidInputError(
                f"{what}: unknown joint names {unknown}{hint}; planning joints are "
                f"{list(model.joint_names)}"
            )
    else:
        given = dict.fromkeys(model.joint_names, limits)
    out: dict[str, float] = {}
    for name, value in given.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InvalidInputError(f"{what}.{name} must be a number, got {value!r:.40}")
        if not (math.isfinite(value) and value > 0):
            raise InvalidInputError(f"{what}.{name} must be a finite number > 0, got {value}")
        out[name] = float(value)
    return out


def link_name(model: RobotModel, link: str | None) -> str | None:
    """`link` if the model has it (None stays None); InvalidInputError otherwise."""
    if link is not None and link not in model.link_names:
        raise InvalidInputError(
            f"end_effector_link {link!r} is not a link of the model; links are "
            f"{list(model.link_names)}"
        )
    return link


def check_same_config(model_id: str, stored: ModelConfig, given: ModelConfig) -> None:
    """ConflictError when `given` sets something to another value than `stored` has."""
    for key in ("acceleration_limits", "jerk_limits", "end_effector_link"):
        new, old = getattr(given, key), getattr(stored, key)
        if new is not None and new != old:
            raise ConflictError(
                f"model {model_id} is already registered with {key}={old}; a model's "
                f"configuration is fixed when it is first registered (asked for {new})"
            )
