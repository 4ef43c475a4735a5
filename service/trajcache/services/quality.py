"""Quality and timing of one trajectory, which every concept of the service shares: the
columns a stored trajectory carries (`services.catalog.trajectories`), the timing and quality of
an answer (`services.bookkeeping.answer_quality`), a Cartesian path's timing. It lies in the
bottom layer of the services, below the catalog that stores the columns, not in the bookkeeping
above it. The metrics themselves are `trajcache.geometry.path_quality`; nothing here reads the
database.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from trajcache.core.config import Settings
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import path_length
from trajcache.geometry.path_quality import Quality, ee_path_length, min_clearance, motion_bound
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import (
    TrajectoryValidator,
    ValidatorCache,
    build_validator,
    validator_for,
)
from trajcache.timing import (
    PathShape,
    TimedTrajectory,
    TimingError,
    TimingMethod,
    kinematic_limits,
    time_trajectory,
)


@dataclass(frozen=True)
class TimingRequest:
    """How a request wants its answer timed."""

    method: TimingMethod = TimingMethod.TOPPRA
    path: PathShape = PathShape.SPLINE
    velocity_scaling: float = 1.0
    acceleration_scaling: float = 1.0
    sample_period_s: float | None = None


def time_states(
    model: RobotModel,
    states: FloatArray,
    settings: Settings,
    request: TimingRequest,
    *,
    validator_fn: Callable[[], TrajectoryValidator | None] | None = None,
) -> TimedTrajectory:
    """Time `states`; a spline is certified with the validator `validator_fn` gives (lazily)."""
    limits = kinematic_limits(
        model,
        settings,
        velocity_scaling=request.velocity_scaling,
        acceleration_scaling=request.acceleration_scaling,
    )

    def certify_fn(samples: FloatArray) -> bool:
        validator = validator_fn() if validator_fn is not None else None
        return validator is not None and validator.validate(samples).valid

    return time_trajectory(
        states,
        base=model.base,
        limits=limits,
        method=request.method,
        path=request.path,
        certify_fn=certify_fn,
        motion_bound=motion_bound(model),
    )


def trajectory_quality(
    model: RobotModel,
    states: FloatArray,
    settings: Settings,
    *,
    scene: Scene | None = None,
    validators: ValidatorCache | None = None,
) -> tuple[Quality, dict[str, Any]]:
    """Every metric of `states`, clearance only with a scene; also details for the JSON column.

    When timing fails (TOPP-RA finds no parameterization), the duration is None and the details
    say why (`timing.error`); the other metrics are still computed. The validator comes from
    `validators` when given, else it is built for this call.
    """
    validator: TrajectoryValidator | None = None
    if scene is not None and validators is not None:
        validator = validator_for(model, scene, settings, cache=validators)
    elif scene is not None:
        validator = build_validator(model, scene, settings)
    details: dict[str, Any] = {}
    try:
        timed = time_states(
            model, states, settings, TimingRequest(), validator_fn=lambda: validator
        )
    except TimingError as exc:  # recorded on the trajectory: its duration stays unknown
        duration = None
        details["timing"] = {"error": str(exc)[:500]}
    else:
        duration = timed.duration
        details["timing"] = {"method": timed.method.value, "path": timed.path.value}
    clearance = None
    if validator is not None:
        clearance = min_clearance(validator.checker, states, resolution=validator.resolution)
    quality = Quality(
        path_length=path_length(states, base=model.base),
        ee_path_length=ee_path_length(model, states),
        min_clearance=None if clearance is None else clearance.distance,
        duration_s=duration,
    )
    if clearance is not None:
        details["clearance"] = {
            "link": clearance.link,
            "object": clearance.object,
            "exact": clearance.exact,
        }
    return quality, details
