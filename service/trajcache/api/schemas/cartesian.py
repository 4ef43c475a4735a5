"""The Cartesian path endpoint's native request and answer."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from trajcache.api.answer_extras import JointTrajectory, TimingOptions, TrajectoryQuality
from trajcache.api.moveit import Quaternion, Vector3
from trajcache.api.schemas.common import FiniteFloat
from trajcache.api.schemas.plan import StateIn
from trajcache.core.request_model import RequestModel

MAX_WAYPOINTS = 256
READY: list[Any] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]


class WaypointIn(RequestModel):
    """A pose of the link: position and orientation, as lists or mappings."""

    position: Vector3 = Field(description="[x, y, z] or {x, y, z}, metres.")
    orientation: Quaternion = Field(
        default_factory=Quaternion, description="[x, y, z, w] or {x, y, z, w}, a unit quaternion."
    )


class CartesianCacheIn(RequestModel):
    """How near a cached Cartesian path must be to serve this request."""

    lookup: bool = Field(default=True, description="Answer from the cache when one is near.")
    store: bool = Field(default=True, description="Store a computed path of fraction 1.0.")
    joint_tolerance: FiniteFloat = Field(
        default=1e-3,
        gt=0,
        le=0.5,
        description="The cached path's start within this of the request's, every value (rad or m).",
    )
    position_tolerance: FiniteFloat = Field(
        default=1e-3,
        gt=0,
        le=0.05,
        description="Each cached waypoint within this distance of the request's (m).",
    )
    orientation_tolerance: FiniteFloat = Field(
        default=1e-2,
        gt=0,
        le=0.5,
        description="Each cached waypoint's orientation within this angle of the request's (rad).",
    )


class CartesianBody(RequestModel):
    """Straight lines of a link's origin from its pose at `start` through `waypoints`; poses in
    the model's base frame (the world frame for a planar base), as IK reads them."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "start": READY,
                    "link": "panda_hand",
                    "waypoints": [
                        {"position": [0.307, 0.0, 0.49], "orientation": [1.0, 0.0, 0.0, 0.0]}
                    ],
                    "max_step": 0.01,
                }
            ]
        },
    )

    start: StateIn = Field(description="As a plan's start: values, a map or a named state.")
    link: str = Field(
        default="",
        max_length=200,
        description="A link of the model, or an SRDF end effector (its parent link); empty: the "
        "model's end-effector link.",
    )
    waypoints: list[WaypointIn] = Field(min_length=1, max_length=MAX_WAYPOINTS)
    max_step: FiniteFloat = Field(
        default=0.01, gt=0, le=1.0, description="Largest step of the link's origin (m)."
    )
    max_rotation_step: FiniteFloat = Field(
        default=0.05, gt=0, le=3.1416, description="Largest step of its orientation (rad)."
    )
    jump_threshold: FiniteFloat = Field(
        default=0.0,
        ge=0,
        description="MoveIt's relative threshold: a joint-space step longer than this × the "
        "mean step stops the path (0: off; paths of 10 steps or more).",
    )
    revolute_jump_threshold: FiniteFloat = Field(
        default=0.0, ge=0, description="A revolute joint's largest step (rad; 0: off)."
    )
    prismatic_jump_threshold: FiniteFloat = Field(
        default=0.0, ge=0, description="A prismatic joint's largest step (m; 0: off)."
    )
    position_tolerance: FiniteFloat = Field(
        default=1e-4, gt=0, le=0.01, description="IK's tolerance at each sample (m)."
    )
    orientation_tolerance: FiniteFloat = Field(
        default=1e-3, gt=0, le=0.1, description="IK's tolerance at each sample (rad)."
    )
    avoid_collisions: bool = Field(
        default=True,
        description="Always honoured as true: every joint motion is certified collision-free "
        "in the robot's current scene (false is listed in `warnings` as not honoured).",
    )
    timing: TimingOptions | None = Field(
        default_factory=TimingOptions,
        description="How the path is timed (default toppra; `method: none` for no timing).",
    )
    cache: CartesianCacheIn = Field(default_factory=CartesianCacheIn)


CARTESIAN_EXAMPLE: dict[str, Any] = {
    "status": "complete",
    "source": "computed",
    "fraction": 1.0,
    "states": [READY, [0.0, -0.74, 0.0, -2.41, 0.0, 1.67, 0.785]],
    "state_names": [f"panda_joint{k}" for k in range(1, 8)],
    "link": "panda_hand",
    "max_deviation_m": 0.0013,
    "message": "",
    "warnings": [],
    "path_id": 12,
    "timings_ms": {"db": 0.5, "lookup": 0.3, "solve": 4.1, "timing": 3.2, "total": 8.1},
}


class CartesianResponse(BaseModel):
    """The joint path that moves the link along the lines, as far as it goes."""

    model_config = ConfigDict(json_schema_extra={"examples": [CARTESIAN_EXAMPLE]})

    status: Literal[
        "complete", "no_ik_solution", "joint_jump", "collision", "too_close", "out_of_limits"
    ] = Field(description="'complete', or why the path stopped short (see `message`).")
    source: Literal["computed", "cache"]
    fraction: float = Field(
        description="MoveIt's: each line counts 1/N of N waypoints; a line stopped short counts "
        "the share of its samples reached."
    )
    states: list[list[float]] = Field(description="The joint path, the start first.")
    state_names: list[str]
    link: str = Field(description="The link moved.")
    max_deviation_m: float = Field(
        description="Bound on the link origin's distance from its line anywhere along the "
        "straight joint motions between states (docs/moveit.md)."
    )
    message: str = ""
    warnings: list[str] = []
    path_id: int | None = Field(description="The stored Cartesian path (null: not stored).")
    joint_trajectory: JointTrajectory | None = None
    quality: TrajectoryQuality | None = None
    timings_ms: dict[str, float] = Field(description="db, lookup, solve, timing, total (ms).")
