"""Request and response bodies of the robot model endpoints (`/v1/models`)."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from trajcache.api.schemas.common import MODEL_ID, SCENE_HASH, WHEN, FiniteFloat, examples
from trajcache.core.request_model import RequestModel
from trajcache.core.suggest import unknown_message
from trajcache.services.errors import InvalidInputError

BaseName = Literal["fixed", "planar"]

URDF_EXAMPLE = (
    '<robot name="arm2"><link name="base"/><link name="l1"><collision><geometry>'
    '<cylinder radius="0.04" length="0.3"/></geometry></collision></link>'
    '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
    '<axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint></robot>'
)
_MODEL: dict[str, Any] = {
    "model_id": MODEL_ID,
    "name": "arm2",
    "base": "planar",
    "joint_names": ["j1"],
    "state_names": ["base_x", "base_y", "base_theta", "j1"],
}
_MODEL_SUMMARY: dict[str, Any] = {**_MODEL, "created_at": WHEN}

PositiveLimit = Annotated[float, Field(gt=0, allow_inf_nan=False)]
JointLimitsIn = PositiveLimit | dict[Annotated[str, Field(max_length=200)], PositiveLimit]


class RobotModelIn(RequestModel):
    """A model to register (JSON form; multipart/form-data takes the same fields)."""

    model_config = ConfigDict(
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
        dict[Annotated[str, Field(min_length=1, max_length=200)], FiniteFloat]
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

    model_config = ConfigDict(json_schema_extra=examples({**_MODEL, "created": True}))

    model_id: str
    name: str
    joint_names: list[str]
    base: BaseName
    state_names: list[str]
    created: bool


class ModelFileOut(BaseModel):
    """A stored mesh file of a model."""

    model_config = ConfigDict(
        json_schema_extra=examples(
            {"path": "meshes/link1.stl", "sha256": SCENE_HASH, "size": 48_284}
        )
    )

    path: str
    sha256: str
    size: int


class RobotModelSummary(BaseModel):
    """A model in a list."""

    model_config = ConfigDict(json_schema_extra=examples(_MODEL_SUMMARY))

    model_id: str
    name: str
    base: BaseName
    joint_names: list[str]
    state_names: list[str]
    created_at: datetime


class RobotModelDetail(RobotModelSummary, ModelSemanticsOut):
    """A model with its links, planning limits (null = unbounded) and files."""

    model_config = ConfigDict(
        json_schema_extra=examples(
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
        json_schema_extra=examples(
            {"items": [_MODEL_SUMMARY], "total": 1, "limit": 100, "offset": 0}
        )
    )

    items: list[RobotModelSummary]
    total: int
    limit: int
    offset: int


# A form's fields: the JSON body's, and the archive as a file.
FORM_FIELDS = (*RobotModelIn.model_fields, "archive")


def check_form_field(key: str, *, repeated: bool) -> None:
    """InvalidInputError naming a field a registration form does not take, or gives twice."""
    if key not in FORM_FIELDS:
        unknown = unknown_message("form field", [key], FORM_FIELDS)
        raise InvalidInputError(f"{unknown} (files: urdf, srdf, archive)")
    if repeated:
        raise InvalidInputError(f"form field {key!r} is given twice")
