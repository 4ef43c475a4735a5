"""Quality and timing of trajectories: at store time, and for answers when a request asks.

The one home of trajectory quality in the service: `trajectory_quality` gives the columns a
stored trajectory carries (`services.catalog.trajectories`, the record writer for planned ones);
`answer_details` gives what a plan request asked for (`AnswerExtras`): quality at a level, and
the answer timed (`services.plan.answers.describe_answer` adds it to the answer). The metrics
themselves are `trajcache.geometry.path_quality`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import Any

import numpy as np

from trajcache.core.config import Settings
from trajcache.geometry.model.robot import BaseType, RobotModel
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
from trajcache.services.context import ServiceContext
from trajcache.timing import (
    PathShape,
    Samples,
    TimedTrajectory,
    TimingError,
    TimingMethod,
    kinematic_limits,
    time_trajectory,
)


class QualityLevel(str, Enum):
    """Which quality metrics an answer carries."""

    BASIC = "basic"  # path lengths (state space, end effector), and duration when timed: cheap
    FULL = "full"  # also clearance to the scene and duration (default timing if none asked)


@dataclass(frozen=True)
class TimingRequest:
    """How a request wants its answer timed."""

    method: TimingMethod = TimingMethod.TOPPRA
    path: PathShape = PathShape.SPLINE
    velocity_scaling: float = 1.0
    acceleration_scaling: float = 1.0
    sample_period_s: float | None = None


@dataclass(frozen=True)
class AnswerExtras:
    """What a request wants added to its answer: quality at a level, and timing if any."""

    timing: TimingRequest | None = None
    quality: QualityLevel = QualityLevel.BASIC


@dataclass
class AnswerDetails:
    """What an answer adds to the states: quality, and the timed trajectory if asked for."""

    quality: Quality
    joint_names: tuple[str, ...] = ()
    timed: TimedTrajectory | None = None
    samples: Samples | None = None
    timings_ms: dict[str, float] = field(default_factory=dict)


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
        planar=model.base is BaseType.PLANAR,
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


def answer_details(
    *,
    ctx: ServiceContext,
    model: RobotModel,
    scene: Scene,
    states: FloatArray,
    timing: TimingRequest | None,
    level: QualityLevel,
) -> AnswerDetails:
    """Quality of an answered trajectory, and its timing when `timing` asks for it.

    `model` and `scene` are the ones the plan flow validated the answer with: nothing is read
    again. The basic level is cheap (tens of microseconds: path lengths); timing and the full
    level cost milliseconds (a spline is certified, clearance measured, in `scene`).
    """
    timed_wanted = timing is not None and timing.method is not TimingMethod.NONE
    began = time.perf_counter()
    details = AnswerDetails(_basic(model, states), joint_names=model.state_names)
    if not timed_wanted and level is QualityLevel.BASIC:
        details.timings_ms["quality"] = (time.perf_counter() - began) * 1e3
        return details
    validator = validator_for(model, scene, ctx.settings, cache=ctx.validators)
    duration = None
    if timed_wanted:
        assert timing is not None
        t = time.perf_counter()
        details.timed = time_states(
            model, states, ctx.settings, timing, validator_fn=lambda: validator
        )
        details.samples = details.timed.sample(
            timing.sample_period_s, max_points=ctx.settings.timing_max_points
        )
        duration = details.timed.duration
        details.timings_ms["timing"] = (time.perf_counter() - t) * 1e3
    clearance = None
    if level is QualityLevel.FULL:
        if duration is None:
            default = time_states(
                model, states, ctx.settings, TimingRequest(), validator_fn=lambda: validator
            )
            duration = default.duration
        found = min_clearance(validator.checker, states, resolution=validator.resolution)
        clearance = None if found is None else found.distance
    details.quality = replace(details.quality, min_clearance=clearance, duration_s=duration)
    spent = (time.perf_counter() - began) * 1e3
    details.timings_ms["quality"] = spent - details.timings_ms.get("timing", 0.0)
    return details


def _basic(model: RobotModel, states: FloatArray) -> Quality:
    array = np.asarray(states, dtype=float)
    return Quality(path_length(array, base=model.base), ee_path_length(model, array))
