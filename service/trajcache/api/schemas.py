"""Request and response bodies of the v1 API (pydantic v2)."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import AliasChoices, BaseModel, ConfigDict, Field

from trajcache.services.robots import ROBOT_ID_PATTERN

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
BaseName = Literal["fixed", "planar"]
SourceName = Literal["real", "sim", "import", "planner"]
ModelId = Annotated[str, Field(min_length=1, max_length=64)]
RobotId = Annotated[str, Field(pattern=ROBOT_ID_PATTERN)]

_URDF_EXAMPLE = (
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


# --- robot models ---------------------------------------------------------------------------


class RobotModelIn(BaseModel):
    """A model to register (JSON form; multipart/form-data takes the same fields)."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={"examples": [{"urdf": _URDF_EXAMPLE, "base": "planar", "name": "arm2"}]},
    )

    urdf: str = Field(min_length=1, description="URDF XML text (no DOCTYPE/ENTITY).")
    base: BaseName = Field(default="fixed", description="'planar' adds x, y, θ base states.")
    joint_names: list[Annotated[str, Field(min_length=1, max_length=200)]] | None = Field(
        default=None, max_length=512, description="Planning joints (default: all movable)."
    )
    name: str | None = Field(default=None, min_length=1, max_length=200)
    archive_base64: str | None = Field(
        default=None, description="Mesh files as a base64 zip or tar(.gz) archive."
    )


class RobotModelOut(BaseModel):
    """A registered model; `created` is false when the same content was registered before."""

    model_id: str
    name: str
    joint_names: list[str]
    base: BaseName
    state_names: list[str]
    created: bool


class ModelFileOut(BaseModel):
    """A stored mesh file of a model."""

    path: str
    sha256: str
    size: int


class RobotModelSummary(BaseModel):
    """A model in a list."""

    model_id: str
    name: str
    base: BaseName
    joint_names: list[str]
    state_names: list[str]
    created_at: datetime


class RobotModelDetail(RobotModelSummary):
    """A model with its links, planning limits (null = unbounded) and files."""

    link_names: list[str]
    lower: list[float | None]
    upper: list[float | None]
    velocity_limits: list[float]
    files: list[ModelFileOut]


class RobotModelPage(BaseModel):
    """A page of models."""

    items: list[RobotModelSummary]
    total: int
    limit: int
    offset: int


# --- robots and scenes ----------------------------------------------------------------------


class RobotIn(BaseModel):
    """The model a robot is an instance of."""

    model_config = ConfigDict(extra="forbid", json_schema_extra={"examples": [{"model_id": "…"}]})

    model_id: ModelId


class RobotOut(BaseModel):
    """A robot; `scene_version` 0 means no scene was uploaded yet."""

    robot_id: str
    model_id: str
    scene_version: int
    created_at: datetime
    updated_at: datetime


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

    version: int
    hash: str


class SceneOut(SceneVersionOut):
    """A robot's current scene in native form."""

    objects: list[dict[str, Any]]
    env: dict[str, float]


# --- trajectories ---------------------------------------------------------------------------


class TrajectoryIn(BaseModel):
    """A trajectory to store: key states ordered as the model's `state_names`."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {
                    "model_id": "…",
                    "states": [[0.0, 0.0], [0.5, -0.2], [1.0, 0.3]],
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

    trajectory_id: int
    created: bool


class TrajectorySummary(BaseModel):
    """A stored trajectory without its states."""

    model_config = ConfigDict(from_attributes=True)

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
    length: float | None
    created_at: datetime


class TrajectoryOut(TrajectorySummary):
    """A stored trajectory with its key states."""

    states: list[list[float]]


class TrajectoryPage(BaseModel):
    """A page of trajectories."""

    items: list[TrajectorySummary]
    total: int
    limit: int
    offset: int


# --- health ---------------------------------------------------------------------------------


class HealthOut(BaseModel):
    """Liveness or readiness."""

    status: Literal["ok", "ready"]
