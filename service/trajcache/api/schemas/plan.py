"""The plan endpoint's request and answer: options, states, rejected candidates."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from trajcache.api.answer_extras import JointTrajectory, TimingOptions, TrajectoryQuality
from trajcache.api.schemas.common import FiniteFloat
from trajcache.core.planners import PLANNER_NAMES
from trajcache.core.request_model import RequestModel


class PlanOptions(RequestModel):
    """Per-request options; each is bounded by the service settings."""

    threshold: FiniteFloat | None = Field(
        default=None, gt=0, description="Lookup distance threshold (default from settings)."
    )
    max_candidates: int | None = Field(
        default=None, ge=1, description="How many cached candidates to try at most."
    )
    fallback: bool = Field(default=True, description="Plan when no cached candidate is valid.")
    lookup: bool = Field(
        default=True,
        description="Look in the cache first; false plans a fresh trajectory (which is stored).",
    )
    budget_s: FiniteFloat | None = Field(
        default=None, gt=0, description="Planning time budget in seconds."
    )
    planner: str | None = Field(
        default=None,
        description="Planner name (default from settings): " + ", ".join(PLANNER_NAMES) + ".",
    )
    match: Literal["full", "arm"] = Field(
        default="full",
        description="'arm' matches on arm joints only when the base does not move, so a motion "
        "learned at one place serves the same motion elsewhere (validation keeps it safe).",
    )
    timing: TimingOptions | None = Field(
        default=None, description="Time the answer: it then carries `joint_trajectory`."
    )
    quality: Literal["basic", "full"] = Field(
        default="basic",
        description="'basic': path lengths (cheap); 'full': also clearance to the scene and "
        "duration (milliseconds more).",
    )

    @field_validator("planner")
    @classmethod
    def _known_planner(cls, name: str | None) -> str | None:
        if name is None:
            return None
        key = name.strip().lower()
        if key not in PLANNER_NAMES:
            raise ValueError(f"unknown planner {name!r}; use one of {', '.join(PLANNER_NAMES)}")
        return key


_ANSWER_EXAMPLES: list[Any] = [
    {
        "status": "success",
        "source": "cache",
        "trajectory_id": 4211,
        "states": [
            [1.0, 0.8, 1.57, 0, -0.5, 0, 0.5, 0, 1.0, 0],
            [1.0, 0.8, 1.57, 0.2, -0.1, 0, 0.9, 0, 1.0, 0],
            [1.0, 0.8, 1.57, 0.4, 0.2, 0, 1.2, 0, 1.0, 0],
        ],
        "candidates_tried": 1,
        "timings_ms": {"lookup": 0.4, "validate": 6.1, "plan": 0.0, "db": 2.3, "total": 9.2},
        "message": "",
        "warnings": [],
        "rejected": [],
    },
    {
        "status": "miss",
        "source": None,
        "trajectory_id": None,
        "states": None,
        "candidates_tried": 1,
        "timings_ms": {"lookup": 0.4, "validate": 3.0, "plan": 0.0, "db": 1.9, "total": 5.6},
        "message": "no valid cached trajectory; fallback planning disabled",
        "rejected": [
            {
                "trajectory_id": 4211,
                "status": "collision",
                "reason": "link 'link5' hits object 'stall_2_door'",
            }
        ],
    },
]


StateIn = (
    Annotated[list[FiniteFloat], Field(min_length=1, max_length=64)]
    | Annotated[dict[Annotated[str, Field(max_length=200)], FiniteFloat], Field(max_length=256)]
    | Annotated[str, Field(min_length=1, max_length=200)]
)


class GoalPoseIn(RequestModel):
    """Where a link must be at the goal: a position and orientation in the model's base frame
    (the world frame for a planar base), within tolerances."""

    link: str = Field(
        default="",
        max_length=200,
        description="A link of the model, or an SRDF end effector (its parent link); empty: the "
        "model's end-effector link.",
    )
    position: Annotated[list[FiniteFloat], Field(min_length=3, max_length=3)] = Field(
        description="[x, y, z], metres."
    )
    orientation: Annotated[list[FiniteFloat], Field(min_length=4, max_length=4)] = Field(
        default=[0.0, 0.0, 0.0, 1.0], description="[x, y, z, w], a unit quaternion."
    )
    position_tolerance: FiniteFloat = Field(
        default=1e-3, gt=0, le=1.0, description="Largest distance from the position (m)."
    )
    orientation_tolerance: FiniteFloat = Field(
        default=1e-2,
        gt=0,
        le=3.1416,
        description="Largest angle of the rotation between the link's orientation and the "
        "target's (rad).",
    )


class PlanBody(RequestModel):
    """A plan request: each state as values in the model's `state_names` order, as a map
    {joint name: value} (held joints may be given at their held values), or as the name of one
    of the model's named states (SRDF group states)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "start": [1.0, 0.8, 1.57, 0, -0.5, 0, 0.5, 0, 1.0, 0],
                    "goal": [1.0, 0.8, 1.57, 0.4, 0.2, 0, 1.2, 0, 1.0, 0],
                    "options": {"threshold": 0.2, "fallback": True},
                }
            ]
        },
    )

    start: StateIn
    goal: StateIn | None = Field(
        default=None, description="The goal state; or give `goal_pose` instead."
    )
    goal_pose: GoalPoseIn | None = Field(
        default=None,
        description="The goal as where a link must be: the state is found among the cached "
        "trajectories' ends, or by inverse kinematics (the answer's `goal_state`).",
    )
    options: PlanOptions = Field(default_factory=PlanOptions)

    @model_validator(mode="after")
    def _one_goal(self) -> PlanBody:
        if (self.goal is None) == (self.goal_pose is None):
            raise ValueError("give exactly one of goal (a state) and goal_pose (a link's pose)")
        return self


class Rejection(BaseModel):
    """A cached candidate that failed validation, and why."""

    trajectory_id: int
    status: str
    reason: str


class ValidationReuse(BaseModel):
    """What a cache answer's validation could skip: `reused` is "none" (the whole path was
    proved), "ends" (only its new first and last segments: the rest was proved in this scene),
    "whole" (the exact path was proved in this scene) or "certificate" (the ends, and the rest
    only against the scene's objects its stored certificate lacks: `objects_reproved` of
    `objects`; `objects_moved` moved by less than the clearance it keeps for them, and
    `objects_clear` lie clear of the swept envelope it keeps, so neither was proved again).
    `ends_proved`: with "ends" or "certificate", the share (0 to 1) of the new end segments
    proved from the clearance measured along the stored ones, without validation."""

    reused: Literal["none", "ends", "whole", "certificate"]
    objects: int | None = None
    objects_reproved: int | None = None
    objects_moved: int | None = None
    objects_clear: int | None = None
    ends_proved: float | None = None


class PlanResponse(BaseModel):
    """The answer: a trajectory and where it came from, or a status saying why there is none."""

    model_config = ConfigDict(json_schema_extra={"examples": _ANSWER_EXAMPLES})

    status: Literal["success", "miss", "failure", "error"]
    source: Literal["cache", "planner", "repaired"] | None
    trajectory_id: int | None
    states: list[list[float]] | None
    candidates_tried: int
    planner: str | None = Field(
        default=None,
        description="The planner that found a planned answer's path (null for a cache answer).",
    )
    timings_ms: dict[str, float] = Field(
        description="Milliseconds per phase: lookup, validate, plan, db, total; a planned answer "
        "adds the planner's own: search, simplify, certify (in the worker), repair, worker (its "
        "whole run) and pool (the round trip around it); a `goal_pose` adds pose_goal (finding "
        "its state, part of lookup)."
    )
    message: str = ""
    warnings: list[str] = Field(
        default=[],
        description="What the caller should know of the answer: 'no scene uploaded: checked "
        "for self-collision only' when the robot never uploaded a scene.",
    )
    rejected: list[Rejection] = []
    joint_trajectory: JointTrajectory | None = None
    quality: TrajectoryQuality | None = None
    goal_state: list[float] | None = Field(
        default=None,
        description="For a `goal_pose`: the goal state it resolved to (the path's last state).",
    )
    goal_found_by: Literal["cached", "ik"] | None = Field(
        default=None,
        description="For a `goal_pose`: `cached` (a cached trajectory's end reaches the pose as "
        "it is) or `ik` (inverse kinematics, from nearby cached states or the start).",
    )
    validation: ValidationReuse | None = Field(
        default=None,
        description="A cache answer's validation: what it could skip (null for other answers).",
    )
