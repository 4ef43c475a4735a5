"""Request and response bodies of the robot and scene endpoints (`/v1/robots`)."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from trajcache.api.schemas.common import (
    MODEL_ID,
    SCENE_HASH,
    WHEN,
    FiniteFloat,
    ModelId,
    examples,
)
from trajcache.core.request_model import RequestModel

_BOX: dict[str, Any] = {
    "id": "table",
    "type": "box",
    "size": [1.2, 0.8, 0.75],
    "pose": {"position": [1.5, 0.0, 0.375], "orientation": [0, 0, 0, 1]},
}


class RobotIn(RequestModel):
    """The model a robot is an instance of."""

    model_config = ConfigDict(json_schema_extra=examples({"model_id": MODEL_ID}))

    model_id: ModelId
    kind: Literal["real", "sim"] | None = Field(
        default=None,
        description="`real` (a physical robot; the default for a new robot) or `sim` (a "
        "simulated one); omitted, an existing robot keeps its kind.",
    )
    joint_values: dict[Annotated[str, Field(min_length=1, max_length=200)], FiniteFloat] | None = (
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
        json_schema_extra=examples(
            {
                "robot_id": "robot-7",
                "model_id": MODEL_ID,
                "kind": "real",
                "scene_version": 2,
                "created_at": WHEN,
                "updated_at": WHEN,
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


class ScenePatchIn(RequestModel):
    """Objects to add or replace (by id), ids to remove, env values to set (null removes)."""

    model_config = ConfigDict(
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

    model_config = ConfigDict(json_schema_extra=examples({"version": 2, "hash": SCENE_HASH}))

    version: int
    hash: str
    warnings: list[str] = Field(
        default_factory=list,
        description="What of the uploaded scene was not applied, or names nothing in it.",
    )


class SceneOut(BaseModel):
    """A robot's current scene in native form."""

    model_config = ConfigDict(
        json_schema_extra=examples(
            {"version": 2, "hash": SCENE_HASH, "objects": [_BOX], "env": {"stall_2_door": 0.52}}
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
