"""Quality and timing of an answer, when its request asks for them.

`answer_details` gives what a request asked for (`AnswerExtras`): quality at a level, and the
answer timed; `services.plan.answers.describe_answer` adds it to a plan answer, and a Cartesian
path's answer carries it too (`services.cartesian.path`). It is handed the settings and the
validator cache it needs, so it works for any concept that answers, below the service context.
A stored trajectory's quality columns, and the timing both share, are `services.quality`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from trajcache.core.config import Settings
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import path_length
from trajcache.geometry.path_quality import Quality, ee_path_length, min_clearance
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import ValidatorCache, validator_for
from trajcache.services.quality import TimingRequest, time_states
from trajcache.timing import Samples, TimedTrajectory, TimingMethod

__all__ = ["AnswerDetails", "AnswerExtras", "QualityLevel", "answer_details"]


class QualityLevel(str, Enum):
    """Which quality metrics an answer carries."""

    BASIC = "basic"  # path lengths (state space, end effector), and duration when timed: cheap
    FULL = "full"  # also clearance to the scene and duration (default timing if none asked)


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


def answer_details(
    *,
    settings: Settings,
    validators: ValidatorCache,
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
    validator = validator_for(model, scene, settings, cache=validators)
    duration = None
    if timed_wanted:
        assert timing is not None
        t = time.perf_counter()
        details.timed = time_states(model, states, settings, timing, validator_fn=lambda: validator)
        details.samples = details.timed.sample(
            timing.sample_period_s, max_points=settings.timing_max_points
        )
        duration = details.timed.duration
        details.timings_ms["timing"] = (time.perf_counter() - t) * 1e3
    clearance = None
    if level is QualityLevel.FULL:
        if duration is None:
            default = time_states(
                model, states, settings, TimingRequest(), validator_fn=lambda: validator
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
