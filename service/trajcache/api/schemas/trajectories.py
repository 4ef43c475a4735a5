"""Request and response bodies of the trajectory endpoints (`/v1/trajectories`)."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import AliasChoices, BaseModel, ConfigDict, Field

from trajcache.api.schemas.common import (
    MODEL_ID,
    SCENE_HASH,
    WHEN,
    FiniteFloat,
    ModelId,
    RobotId,
    examples,
)
from trajcache.core.request_model import RequestModel

SourceName = Literal["real", "sim", "import", "planner"]

_TRAJECTORY_SUMMARY: dict[str, Any] = {
    "trajectory_id": 1,
    "model_id": MODEL_ID,
    "source": "real",
    "robot_id": "robot-7",
    "n_states": 3,
    "dof": 4,
    "start": [0.0, 0.0, 0.0, 0.0],
    "goal": [1.0, 0.0, 0.0, 0.3],
    "scene_hash": SCENE_HASH,
    "env": {"stall_2_door": 0.0},
    "hits": 12,
    "failures": 1,
    "last_used_at": WHEN,
    "planning_time_ms": 68.2,
    "length": 1.08,
    "created_at": WHEN,
}


class TrajectoryIn(RequestModel):
    """A trajectory to store: key states ordered as the model's `state_names`."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "model_id": MODEL_ID,
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

    model_config = ConfigDict(json_schema_extra=examples({"trajectory_id": 1, "created": True}))

    trajectory_id: int
    created: bool


class TrajectorySummary(BaseModel):
    """A stored trajectory without its states."""

    model_config = ConfigDict(from_attributes=True, json_schema_extra=examples(_TRAJECTORY_SUMMARY))

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
    quality_pending: bool = Field(
        default=False,
        description="Imported, its quality (lengths, clearance, duration) not computed yet: "
        "the service computes it in the background, and the quality fields stay null till then.",
    )
    created_at: datetime


class TrajectoryOut(TrajectorySummary):
    """A stored trajectory with its key states."""

    model_config = ConfigDict(
        json_schema_extra=examples(
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
        json_schema_extra=examples(
            {"items": [_TRAJECTORY_SUMMARY], "total": 1, "limit": 100, "offset": 0}
        )
    )

    items: list[TrajectorySummary]
    total: int
    limit: int
    offset: int
