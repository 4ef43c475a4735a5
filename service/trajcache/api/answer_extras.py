"""Plan-answer extras in the API's shapes: the timing and quality options, the JointTrajectory
and quality fields. What they hold is computed by the services
(`services.bookkeeping.answer_quality`)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from trajcache.core.request_model import RequestModel
from trajcache.services.bookkeeping.answer_quality import (
    AnswerDetails,
    AnswerExtras,
    QualityLevel,
)
from trajcache.services.quality import TimingRequest
from trajcache.timing import PathShape, TimingMethod

Scaling = Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)]


class TimingOptions(RequestModel):
    """How to time the answered trajectory (the answer then carries `joint_trajectory`)."""

    model_config = ConfigDict(
        json_schema_extra={"examples": [{"method": "toppra", "velocity_scaling": 0.5}]},
    )

    method: Literal["toppra", "jerk_limited", "none"] = Field(
        default="toppra",
        description="'toppra': time-optimal under velocity and acceleration limits (TOPP-RA); "
        "'jerk_limited': jerk-bounded S-curves (Ruckig), at rest at every key state; 'none'.",
    )
    path: Literal["spline", "linear"] = Field(
        default="spline",
        description="toppra only. 'spline': a cubic spline through every key state without "
        "stops, itself certified against the robot's scene (else 'linear' is used); 'linear': "
        "the validated straight segments exactly, at rest where the direction changes.",
    )
    velocity_scaling: Scaling = Field(default=1.0, description="Factor on velocity limits.")
    acceleration_scaling: Scaling = Field(
        default=1.0, description="Factor on acceleration (and jerk) limits."
    )
    sample_period_s: float | None = Field(
        default=None,
        ge=0.001,
        le=60.0,
        allow_inf_nan=False,
        description="Sample every this many seconds (plus the end); default: at the key states.",
    )


class JointTrajectoryPoint(BaseModel):
    """One point, as in ROS `trajectory_msgs/JointTrajectoryPoint`."""

    positions: list[float]
    velocities: list[float]
    accelerations: list[float]
    time_from_start: float = Field(description="Seconds from the start of the trajectory.")


class JointTrajectory(BaseModel):
    """The timed trajectory in the shape of ROS `trajectory_msgs/JointTrajectory`.

    `joint_names` are the model's state names (base x, y, θ first for a planar base). The base
    angle is continuous along the trajectory (it may leave [-π, π]; equal to the state's angle
    modulo 2π). `method` and `path` say how it was timed ('path' may fall back to 'linear').
    """

    joint_names: list[str]
    points: list[JointTrajectoryPoint]
    method: Literal["toppra", "jerk_limited"]
    path: Literal["spline", "linear"]
    duration_s: float


class TrajectoryQuality(BaseModel):
    """Quality of the answered trajectory; null where not computed (see `options.quality`)."""

    path_length: float = Field(description="State-space length (base angle the short way).")
    ee_path_length: float | None = Field(description="End-effector path length (m).")
    min_clearance: float | None = Field(
        description="Smallest distance to the scene (m); full quality only (null: no obstacles)."
    )
    duration_s: float | None = Field(
        description="Duration after timing (s); with timing, or full quality."
    )


def answer_extras(timing: TimingOptions | None, quality: Literal["basic", "full"]) -> AnswerExtras:
    """The service's extras request of the `timing` and `quality` options."""
    request = None
    if timing is not None and timing.method != "none":
        request = TimingRequest(
            method=TimingMethod(timing.method),
            path=PathShape(timing.path),
            velocity_scaling=timing.velocity_scaling,
            acceleration_scaling=timing.acceleration_scaling,
            sample_period_s=timing.sample_period_s,
        )
    return AnswerExtras(timing=request, quality=QualityLevel(quality))


def extras_body(details: AnswerDetails | None) -> dict[str, Any]:
    """The `joint_trajectory` and `quality` fields of an answer with these details."""
    if details is None:
        return {"joint_trajectory": None, "quality": None}
    joint_trajectory = None
    if details.timed is not None and details.samples is not None:
        samples = details.samples
        joint_trajectory = {
            "joint_names": list(details.joint_names),
            "points": [
                {"positions": p, "velocities": v, "accelerations": a, "time_from_start": t}
                for p, v, a, t in zip(
                    samples.positions.tolist(),
                    samples.velocities.tolist(),
                    samples.accelerations.tolist(),
                    samples.times.tolist(),
                    strict=True,
                )
            ],
            "method": details.timed.method.value,
            "path": details.timed.path.value,
            "duration_s": details.timed.duration,
        }
    return {"joint_trajectory": joint_trajectory, "quality": details.quality.as_dict()}
