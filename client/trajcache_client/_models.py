"""Typed bodies of the v1 API; answers keep fields a newer service adds (in `model_extra`)."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Generic, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field

T = TypeVar("T")

BaseType = Literal["fixed", "planar"]
Source = Literal["real", "sim", "import", "planner"]
RobotKind = Literal["real", "sim"]
SkipReason = Literal["adjacent", "rigid", "proven", "srdf"]
PlanStatus = Literal["success", "miss", "failure", "error"]
PlanSource = Literal["cache", "planner", "repaired"]
Requester = Literal["robot", "seed_job"]  # who asked for a plan
GoalKind = Literal["joint", "pose", "unknown"]  # a plan's goal; unknown: recorded before kinds


class _Answer(BaseModel):
    """An answer body: unknown fields are kept, not rejected."""

    model_config = ConfigDict(extra="allow", frozen=True)


class Page(_Answer, Generic[T]):
    """One page of a list; `total` counts every match."""

    items: list[T]
    total: int
    limit: int
    offset: int


class SkippedPair(_Answer):
    """Two links whose self-collisions are not checked, and why.

    `reason` is one of `SkipReason`: "adjacent" (one rigid body, or joined by a joint), "rigid"
    (no planning joint moves one relative to the other), "proven" (apart within the joint
    limits) or "srdf" (disabled by the SRDF); a reason a newer service adds is kept as text.
    """

    links: tuple[str, str]
    reason: SkipReason | str


class _ModelSemantics(_Answer):
    """What a model's answer says about self-collision, held joints and named states."""

    skipped_pairs: list[SkippedPair] = Field(default_factory=list)
    held_joints: dict[str, float] = Field(default_factory=dict)  # joint -> its held value
    named_states: dict[str, list[float]] = Field(default_factory=dict)  # planning joint values
    warnings: list[str] = Field(default_factory=list)  # what of the SRDF was not applied


class RobotModel(_ModelSemantics):
    """A registered model; `created` is false when the same content was registered before."""

    model_id: str
    name: str
    joint_names: list[str]
    base: BaseType
    state_names: list[str]
    created: bool


class RobotModelSummary(_Answer):
    """A model in a list."""

    model_id: str
    name: str
    base: BaseType
    joint_names: list[str]
    state_names: list[str]
    created_at: datetime


class ModelFile(_Answer):
    """A mesh file stored with a model."""

    path: str
    sha256: str
    size: int


class RobotModelDetail(RobotModelSummary, _ModelSemantics):
    """A model with its links, planning and timing limits (None = unbounded) and files."""

    link_names: list[str]
    lower: list[float | None]
    upper: list[float | None]
    velocity_limits: list[float]
    acceleration_limits: list[float] | None = None
    jerk_limits: list[float] | None = None
    end_effector_link: str | None = None
    files: list[ModelFile]


class Robot(_Answer):
    """A robot; `scene_version` 0 means it has no scene yet.

    `kind` is one of `RobotKind` ("real" or "sim"); `joint_values` are the joints it holds
    otherwise than its model.
    """

    robot_id: str
    model_id: str
    kind: RobotKind | str
    scene_version: int
    created_at: datetime
    updated_at: datetime
    joint_values: dict[str, float] = Field(default_factory=dict)


class SceneVersion(_Answer):
    """The version number and content hash of a scene, and what of it was not applied."""

    version: int
    hash: str
    warnings: list[str] = Field(default_factory=list)


class Scene(_Answer):
    """A robot's current scene in native form, with the contact it allows and attached objects."""

    version: int
    hash: str
    objects: list[dict[str, Any]]
    env: dict[str, float]
    allowed_collisions: list[list[str]] = Field(default_factory=list)
    attached_objects: list[dict[str, Any]] = Field(default_factory=list)


class TimingOptions(BaseModel):
    """How to time a plan answer (it then carries `joint_trajectory`); None: service default."""

    model_config = ConfigDict(extra="allow")

    method: Literal["toppra", "jerk_limited", "none"] | None = None
    path: Literal["spline", "linear"] | None = None
    velocity_scaling: float | None = Field(default=None, gt=0, le=1)
    acceleration_scaling: float | None = Field(default=None, gt=0, le=1)
    sample_period_s: float | None = Field(default=None, ge=0.001, le=60)


class JointTrajectoryPoint(_Answer):
    """One timed point: positions, velocities and accelerations per state value."""

    positions: list[float]
    velocities: list[float]
    accelerations: list[float]
    time_from_start: float


class JointTrajectory(_Answer):
    """A timed trajectory, shaped like ROS trajectory_msgs/JointTrajectory."""

    joint_names: list[str]
    points: list[JointTrajectoryPoint]
    method: Literal["toppra", "jerk_limited"] | str
    path: Literal["spline", "linear"] | str
    duration_s: float


class TrajectoryQuality(_Answer):
    """Measures of a returned trajectory (min_clearance only with full quality)."""

    path_length: float
    ee_path_length: float | None = None
    min_clearance: float | None = None
    duration_s: float | None = None


class PlanOptions(BaseModel):
    """Per-request plan options; None leaves the service default. Unknown options pass through."""

    model_config = ConfigDict(extra="allow")

    threshold: float | None = Field(default=None, gt=0)
    max_candidates: int | None = Field(default=None, ge=1)
    fallback: bool | None = None
    budget_s: float | None = Field(default=None, gt=0)
    planner: str | None = None
    match: Literal["full", "arm"] | None = None
    lookup: bool | None = None
    quality: Literal["basic", "full"] | None = None
    timing: TimingOptions | None = None


class Rejection(_Answer):
    """A cached candidate that failed validation, and why."""

    trajectory_id: int
    status: str
    reason: str


class ValidationReuse(_Answer):
    """What a cache answer's validation could skip: `reused` is "none", "ends", "whole" or
    "certificate" (then `objects_reproved` of the scene's `objects` were proved again, while
    `objects_moved` moved within the clearance it keeps and `objects_clear` lie clear of its
    swept envelope); `ends_proved`: the share of the new end segments proved from stored
    clearances."""

    reused: Literal["none", "ends", "whole", "certificate"]
    objects: int | None = None
    objects_reproved: int | None = None
    objects_moved: int | None = None
    objects_clear: int | None = None
    ends_proved: float | None = None


class ContactPair(_Answer):
    """A link and what it touches: a scene object (`scene`) or another link (`self`)."""

    link: str
    other: str
    kind: Literal["scene", "self"] | str


class RejectedCandidate(_Answer):
    """A cached candidate that failed validation, and where: its first failing sample.

    `sample` is the validation sample at (or just before) the failing `state`, `at` the
    fraction of the step to the next one, of `samples` in all; `pairs` are the link and object
    (or the two links) at fault, `joints` those out of limits. `start` and `goal` are the
    request's, which the candidate was adapted to; `held` the joint values the robot held
    outside the planning joints then (`{}`: its model's).
    """

    trajectory_id: int
    reversed: bool
    status: Literal["collision", "out_of_limits", "too_close"] | str
    reason: str
    start: list[float]
    goal: list[float]
    sample: int | None = None
    at: float | None = None
    samples: int | None = None
    segment: int | None = None
    state: list[float] | None = None
    pairs: list[ContactPair] = Field(default_factory=list)
    joints: list[str] = Field(default_factory=list)
    held: dict[str, float] | None = None


class PlanResult(_Answer):
    """A plan answer: a trajectory and where it came from, or a status saying why there is none.

    `status` is "success", "miss" (no valid candidate, no planning), "failure" (no path within
    the budget) or "error" (the planner could not run); `source` is "cache" or "planner".
    """

    status: PlanStatus | str
    source: PlanSource | str | None
    trajectory_id: int | None
    states: list[list[float]] | None
    candidates_tried: int
    timings_ms: dict[str, float]
    planner: str | None = None  # the planner that found a planned answer's path
    message: str = ""
    warnings: list[str] = Field(default_factory=list)  # e.g. no scene uploaded
    rejected: list[Rejection] = Field(default_factory=list)
    quality: TrajectoryQuality | None = None
    joint_trajectory: JointTrajectory | None = None
    validation: ValidationReuse | None = None  # a cache answer's: what its validation skipped
    goal_state: list[float] | None = None  # a goal_pose's state (the path's last)
    goal_found_by: Literal["cached", "ik"] | None = None  # how that state was found

    @property
    def ok(self) -> bool:
        """True when the answer carries a trajectory."""
        return self.status == "success" and self.states is not None


class IkResult(_Answer):
    """An IK answer: the state that puts the link at the pose, or a status saying why there is
    none ("not_found" within the budget, or "in_collision": reached only in collision)."""

    status: Literal["success", "not_found", "in_collision"]
    state: list[float] | None
    state_names: list[str]
    link: str
    position_error: float | None
    orientation_error: float | None
    solutions: int
    rejected: int
    attempts: int
    message: str = ""
    timings_ms: dict[str, float]

    @property
    def ok(self) -> bool:
        """True when the answer carries a state."""
        return self.status == "success" and self.state is not None


class CartesianResult(_Answer):
    """A Cartesian path answer: the joint path moving the link along straight lines through
    the waypoints, as far as it goes (`fraction`, MoveIt's), and why it stopped (`status`:
    "complete", "no_ik_solution", "joint_jump", "collision", "too_close", "out_of_limits")."""

    status: (
        Literal[
            "complete", "no_ik_solution", "joint_jump", "collision", "too_close", "out_of_limits"
        ]
        | str
    )
    source: Literal["computed", "cache"] | str
    fraction: float
    states: list[list[float]]
    state_names: list[str]
    link: str
    max_deviation_m: float  # bound on the link's distance from its lines between states
    message: str = ""
    warnings: list[str] = Field(default_factory=list)
    path_id: int | None
    joint_trajectory: JointTrajectory | None = None
    quality: TrajectoryQuality | None = None
    timings_ms: dict[str, float]

    @property
    def ok(self) -> bool:
        """True when the whole path was reached."""
        return self.fraction == 1.0


class TrajectoryCreated(_Answer):
    """A stored trajectory's id; `created` is false when it was already stored."""

    trajectory_id: int
    created: bool


class TrajectorySummary(_Answer):
    """A stored trajectory without its states."""

    trajectory_id: int
    model_id: str
    source: str
    robot_id: str | None
    n_states: int
    dof: int
    start: list[float]
    goal: list[float]
    scene_hash: str | None
    env: dict[str, float]
    hits: int
    failures: int
    last_used_at: datetime | None
    planning_time_ms: float | None
    length: float | None
    ee_length: float | None = None
    min_clearance: float | None = None
    duration_s: float | None = None
    quality_pending: bool = False  # imported; quality computed in the background
    created_at: datetime


class PlanEvent(_Answer):
    """One plan request: who asked, how it ended, and where the time went (ms)."""

    event_id: int
    created_at: datetime
    robot_id: str
    requester: Requester | str = "robot"  # a seed job's robot_id is `seed-job-<id>`
    model_id: str
    scene_hash: str | None
    status: str
    source: str | None
    trajectory_id: int | None
    candidates_tried: int
    lookup_ms: float
    validate_ms: float
    plan_ms: float
    total_ms: float
    error: str | None
    seed: int | None = None
    goal_kind: GoalKind | None = None  # None: recorded before the kind was, or a refusal
    rejections: list[RejectedCandidate] = Field(default_factory=list)


class Trajectory(TrajectorySummary):
    """A stored trajectory with its key states and its most recent plan events."""

    states: list[list[float]]
    usage_history: list[PlanEvent] = Field(default_factory=list)


class Health(_Answer):
    """Liveness (`ok`) or readiness (`ready`)."""

    status: Literal["ok", "ready"] | str
