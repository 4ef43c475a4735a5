"""Request and response bodies of the v1 API (pydantic v2)."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import AliasChoices, BaseModel, ConfigDict, Field

from trajcache.services.robots import ROBOT_ID_PATTERN

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
BaseName = Literal["fixed", "planar"]
FiniteNumber = Annotated[float, Field(allow_inf_nan=False)]
SourceName = Literal["real", "sim", "import", "planner"]
ModelId = Annotated[str, Field(min_length=1, max_length=64)]
RobotId = Annotated[str, Field(pattern=ROBOT_ID_PATTERN)]

URDF_EXAMPLE = (
    '<robot name="arm2"><link name="base"/><link name="l1"><collision><geometry>'
    '<cylinder radius="0.04" length="0.3"/></geometry></collision></link>'
    '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
    '<axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint></robot>'
)
_BOX: dict[str, Any] = {
    "id": "table",
    "type": "box",
    "size": [1.2, 0.8, 0.75],
    "pose": {"position": [1.5, 0.0, 0.375], "orientation": [0, 0, 0, 1]},
}
# Answers of the examples above, as the service gives them (OpenAPI examples of the responses).
_MODEL_ID = "5158592d7f5559c728b6d23f76857a89890f358d7aa40994d9e2338ac93ec821"
_SCENE_HASH = "08dd82870f84ed8b43d17f3baca4d6c55c6de216fbfee2996678642b82b81e4a"
_WHEN = "2025-06-02T09:25:01.941173Z"
_MODEL: dict[str, Any] = {
    "model_id": _MODEL_ID,
    "name": "arm2",
    "base": "planar",
    "joint_names": ["j1"],
    "state_names": ["base_x", "base_y", "base_theta", "j1"],
}
_MODEL_SUMMARY: dict[str, Any] = {**_MODEL, "created_at": _WHEN}
_TRAJECTORY_SUMMARY: dict[str, Any] = {
    "trajectory_id": 1,
    "model_id": _MODEL_ID,
    "source": "real",
    "robot_id": "robot-7",
    "n_states": 3,
    "dof": 4,
    "start": [0.0, 0.0, 0.0, 0.0],
    "goal": [1.0, 0.0, 0.0, 0.3],
    "scene_hash": _SCENE_HASH,
    "env": {"stall_2_door": 0.0},
    "hits": 12,
    "failures": 1,
    "last_used_at": _WHEN,
    "planning_time_ms": 68.2,
    "length": 1.08,
    "created_at": _WHEN,
}


def _examples(*examples: dict[str, Any]) -> dict[str, Any]:
    return {"examples": list(examples)}


# --- errors ---------------------------------------------------------------------------------


class FieldErrorOut(BaseModel):
    """One invalid field of a request."""

    loc: list[str | int] = Field(description="Where: `body`, `query` or `path`, then the field.")
    msg: str
    type: str


class ErrorOut(BaseModel):
    """Every error answer: a readable `detail`; request validation also lists the fields."""

    model_config = ConfigDict(
        json_schema_extra=_examples(
            {
                "detail": "body.start[1]: Input should be a finite number",
                "errors": [
                    {
                        "loc": ["body", "start", 1],
                        "msg": "Input should be a finite number",
                        "type": "finite_number",
                    }
                ],
            }
        )
    )

    detail: str
    errors: list[FieldErrorOut] | None = Field(
        default=None, description="The invalid fields (first 10), on request validation errors."
    )


# --- robot models ---------------------------------------------------------------------------

PositiveLimit = Annotated[float, Field(gt=0, allow_inf_nan=False)]
JointLimitsIn = PositiveLimit | dict[Annotated[str, Field(max_length=200)], PositiveLimit]


class RobotModelIn(BaseModel):
    """A model to register (JSON form; multipart/form-data takes the same fields)."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={"examples": [{"urdf": URDF_EXAMPLE, "base": "planar", "name": "arm2"}]},
    )

    urdf: str = Field(min_length=1, description="URDF XML text (no DOCTYPE/ENTITY).")
    srdf: str | None = Field(
        default=None,
        min_length=1,
        description="SRDF XML text: its `disable_collisions` pairs are not checked, its "
        "`group_state`s become named states, and `group` picks one of its groups.",
    )
    base: BaseName = Field(default="fixed", description="'planar' adds x, y, θ base states.")
    joint_names: list[Annotated[str, Field(min_length=1, max_length=200)]] | None = Field(
        default=None,
        max_length=512,
        description="Planning joints (default: the SRDF `group`'s, else every movable joint "
        "that does not mimic another).",
    )
    group: str | None = Field(
        default=None,
        min_length=1,
        max_length=200,
        description="An SRDF group whose movable joints are the planning joints.",
    )
    joint_values: (
        dict[Annotated[str, Field(min_length=1, max_length=200)], FiniteNumber]
        | Annotated[str, Field(min_length=1, max_length=200)]
        | None
    ) = Field(
        default=None,
        description="Values of joints held outside the planning joints (e.g. a gripper's "
        "opening), by joint name or as the name of an SRDF group_state; others are held at 0 "
        "within their limits, and mimic joints follow their leader. Part of the model id.",
    )
    name: str | None = Field(default=None, min_length=1, max_length=200)
    archive_base64: str | None = Field(
        default=None, description="Mesh files as a base64 zip or tar(.gz) archive."
    )
    acceleration_limits: JointLimitsIn | None = Field(
        default=None,
        description="Acceleration limits of the planning joints for timing (rad/s², m/s² for "
        "prismatic joints): one value for all, or by joint name; joints left out use the "
        "service default (TRAJCACHE_TIMING_JOINT_ACCELERATION). Fixed at first registration.",
    )
    jerk_limits: JointLimitsIn | None = Field(
        default=None,
        description="Jerk limits (rad/s³) for jerk-limited timing, like acceleration_limits "
        "(default TRAJCACHE_TIMING_JOINT_JERK).",
    )
    end_effector_link: str | None = Field(
        default=None,
        min_length=1,
        max_length=200,
        description="Link whose path is measured as the end-effector path (default: the tip "
        "of the longest kinematic chain).",
    )


class SkippedPairOut(BaseModel):
    """A pair of links whose self-collisions are not checked."""

    links: tuple[str, str]
    reason: Literal["adjacent", "rigid", "proven", "srdf"] = Field(
        description="'adjacent': in one rigid body or joined by a joint; 'rigid': no planning "
        "joint moves one relative to the other; 'proven': proven apart within the joint limits; "
        "'srdf': disabled by the SRDF."
    )


class ModelSemanticsOut(BaseModel):
    """What a model's answer tells of its self-collision checks, held joints and named states."""

    skipped_pairs: list[SkippedPairOut] = Field(
        default_factory=list, description="Self-collision pairs that are not checked, and why."
    )
    held_joints: dict[str, float] = Field(
        default_factory=dict, description="Joints outside the planning joints and their values."
    )
    named_states: dict[str, list[float]] = Field(
        default_factory=dict,
        description="SRDF group states usable as a plan's start or goal: planning joint values.",
    )
    warnings: list[str] = Field(
        default_factory=list, description="What of the SRDF was not applied, and why."
    )


class RobotModelOut(ModelSemanticsOut):
    """A registered model; `created` is false when the same content was registered before."""

    model_config = ConfigDict(json_schema_extra=_examples({**_MODEL, "created": True}))

    model_id: str
    name: str
    joint_names: list[str]
    base: BaseName
    state_names: list[str]
    created: bool


class ModelFileOut(BaseModel):
    """A stored mesh file of a model."""

    model_config = ConfigDict(
        json_schema_extra=_examples(
            {"path": "meshes/link1.stl", "sha256": _SCENE_HASH, "size": 48_284}
        )
    )

    path: str
    sha256: str
    size: int


class RobotModelSummary(BaseModel):
    """A model in a list."""

    model_config = ConfigDict(json_schema_extra=_examples(_MODEL_SUMMARY))

    model_id: str
    name: str
    base: BaseName
    joint_names: list[str]
    state_names: list[str]
    created_at: datetime


class RobotModelDetail(RobotModelSummary, ModelSemanticsOut):
    """A model with its links, planning limits (null = unbounded) and files."""

    model_config = ConfigDict(
        json_schema_extra=_examples(
            {
                **_MODEL_SUMMARY,
                "link_names": ["base", "l1"],
                "lower": [None, None, -3.141592653589793, -3.0],
                "upper": [None, None, 3.141592653589793, 3.0],
                "velocity_limits": [0.5, 0.5, 1.0, 1.0],
                "files": [],
            }
        )
    )

    link_names: list[str]
    lower: list[float | None]
    upper: list[float | None]
    velocity_limits: list[float]
    acceleration_limits: list[float] | None = Field(
        default=None, description="Acceleration limits timing uses, per state value."
    )
    jerk_limits: list[float] | None = Field(
        default=None, description="Jerk limits jerk-limited timing uses, per state value."
    )
    end_effector_link: str | None = Field(
        default=None, description="The link whose path is the end-effector path."
    )
    files: list[ModelFileOut]


class RobotModelPage(BaseModel):
    """A page of models."""

    model_config = ConfigDict(
        json_schema_extra=_examples(
            {"items": [_MODEL_SUMMARY], "total": 1, "limit": 100, "offset": 0}
        )
    )

    items: list[RobotModelSummary]
    total: int
    limit: int
    offset: int


# --- robots and scenes ----------------------------------------------------------------------


class RobotIn(BaseModel):
    """The model a robot is an instance of."""

    model_config = ConfigDict(extra="forbid", json_schema_extra=_examples({"model_id": _MODEL_ID}))

    model_id: ModelId
    kind: Literal["real", "sim"] | None = Field(
        default=None,
        description="`real` (a physical robot; the default for a new robot) or `sim` (a "
        "simulated one); omitted, an existing robot keeps its kind.",
    )
    joint_values: dict[Annotated[str, Field(min_length=1, max_length=200)], FiniteNumber] | None = (
        Field(
            default=None,
            max_length=256,
            description="Values at which this robot holds joints outside the planning joints, "
            "where they differ from its model's (e.g. the gripper open). Its plans are checked "
            "with them; trajectories cached by robots that hold them otherwise are validated "
            "again, never trusted. Omitted: kept; `{}`: the model's values.",
        )
    )


class RobotOut(BaseModel):
    """A robot; `scene_version` 0 means no scene was uploaded yet."""

    model_config = ConfigDict(
        json_schema_extra=_examples(
            {
                "robot_id": "robot-7",
                "model_id": _MODEL_ID,
                "kind": "real",
                "scene_version": 2,
                "created_at": _WHEN,
                "updated_at": _WHEN,
            }
        )
    )

    robot_id: str
    model_id: str
    kind: Literal["real", "sim"]
    scene_version: int
    created_at: datetime
    updated_at: datetime
    joint_values: dict[str, float] = Field(
        default_factory=dict, description="Joints the robot holds otherwise than its model."
    )


class SceneIn(BaseModel):
    """A scene in native form (documentation of the PUT body; a MoveIt world is accepted too)."""

    model_config = ConfigDict(json_schema_extra={"examples": [{"objects": [_BOX], "env": {}}]})

    objects: list[dict[str, Any]] = Field(default_factory=list)
    env: dict[str, float] = Field(default_factory=dict)


class ScenePatchIn(BaseModel):
    """Objects to add or replace (by id), ids to remove, env values to set (null removes)."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {
                    "upsert": [{**_BOX, "id": "door", "size": [0.05, 0.9, 2.0]}],
                    "remove": ["cart"],
                    "env": {"stall_2_door": 0.52},
                }
            ]
        },
    )

    upsert: list[dict[str, Any]] = Field(default_factory=list)
    remove: list[str] = Field(default_factory=list)
    env: dict[str, FiniteFloat | None] = Field(default_factory=dict)


class SceneVersionOut(BaseModel):
    """The version number and content hash of a scene."""

    model_config = ConfigDict(json_schema_extra=_examples({"version": 2, "hash": _SCENE_HASH}))

    version: int
    hash: str
    warnings: list[str] = Field(
        default_factory=list,
        description="What of the uploaded scene was not applied, or names nothing in it.",
    )


class SceneOut(BaseModel):
    """A robot's current scene in native form."""

    model_config = ConfigDict(
        json_schema_extra=_examples(
            {"version": 2, "hash": _SCENE_HASH, "objects": [_BOX], "env": {"stall_2_door": 0.52}}
        )
    )

    version: int
    hash: str
    objects: list[dict[str, Any]]
    env: dict[str, float]
    allowed_collisions: list[list[str]] = Field(
        default_factory=list, description="Name pairs whose contact the scene allows."
    )
    attached_objects: list[dict[str, Any]] = Field(
        default_factory=list, description="Objects that travel with a robot link."
    )


# --- trajectories ---------------------------------------------------------------------------


class TrajectoryIn(BaseModel):
    """A trajectory to store: key states ordered as the model's `state_names`."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {
                    "model_id": _MODEL_ID,
                    "states": [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.2], [1.0, 0.0, 0.0, 0.3]],
                    "source": "real",
                    "robot_id": "robot-7",
                }
            ]
        },
    )

    model_id: ModelId
    states: list[list[FiniteFloat]] = Field(description="Key states, at least 2.")
    source: SourceName = "real"
    robot_id: RobotId | None = None
    scene_hash: str | None = Field(default=None, min_length=1, max_length=64)
    env: dict[str, FiniteFloat] | None = None
    planning_time_ms: FiniteFloat | None = Field(default=None, ge=0)


class TrajectoryCreated(BaseModel):
    """The stored trajectory's id; `created` is false when it was already stored."""

    model_config = ConfigDict(json_schema_extra=_examples({"trajectory_id": 1, "created": True}))

    trajectory_id: int
    created: bool


class TrajectorySummary(BaseModel):
    """A stored trajectory without its states."""

    model_config = ConfigDict(
        from_attributes=True, json_schema_extra=_examples(_TRAJECTORY_SUMMARY)
    )

    trajectory_id: int = Field(validation_alias=AliasChoices("trajectory_id", "id"))
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
    length: float | None = Field(description="State-space path length (quality at store time).")
    ee_length: float | None = Field(
        default=None, description="End-effector path length (m) at store time."
    )
    min_clearance: float | None = Field(
        default=None, description="Smallest distance to its recorded scene (m) at store time."
    )
    duration_s: float | None = Field(
        default=None, description="Duration after time-optimal timing (s) at store time."
    )
    created_at: datetime


class TrajectoryOut(TrajectorySummary):
    """A stored trajectory with its key states."""

    model_config = ConfigDict(
        json_schema_extra=_examples(
            {
                **_TRAJECTORY_SUMMARY,
                "states": [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.2], [1.0, 0.0, 0.0, 0.3]],
            }
        )
    )

    states: list[list[float]]


class TrajectoryPage(BaseModel):
    """A page of trajectories."""

    model_config = ConfigDict(
        json_schema_extra=_examples(
            {"items": [_TRAJECTORY_SUMMARY], "total": 1, "limit": 100, "offset": 0}
        )
    )

    items: list[TrajectorySummary]
    total: int
    limit: int
    offset: int


# --- health ---------------------------------------------------------------------------------


class HealthOut(BaseModel):
    """Liveness or readiness."""

    model_config = ConfigDict(json_schema_extra=_examples({"status": "ok"}, {"status": "ready"}))

    status: Literal["ok", "ready"]
