"""The IK endpoint's native request and answer."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from trajcache.api.moveit import Quaternion, Vector3
from trajcache.api.schemas.common import FiniteFloat
from trajcache.api.schemas.plan import StateIn
from trajcache.core.request_model import RequestModel
from trajcache.services.ik.solve import IK_BUDGET_MAX_S, IK_BUDGET_S

MAX_SOLUTIONS = 16


class IkBody(RequestModel):
    """Where a link must be. The pose is in the model's base frame (its root link), or in the
    world frame for a planar base; vectors and quaternions as lists or mappings."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "link": "panda_hand",
                    "position": [0.4, 0.1, 0.5],
                    "orientation": [1.0, 0.0, 0.0, 0.0],
                    "seed": [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
                }
            ]
        },
    )

    link: str = Field(
        default="",
        max_length=200,
        description="A link of the model, or an SRDF end effector (its parent link); empty: the "
        "model's end-effector link.",
    )
    position: Vector3 = Field(description="[x, y, z] or {x, y, z}, metres.")
    orientation: Quaternion = Field(
        default_factory=Quaternion, description="[x, y, z, w] or {x, y, z, w}, a unit quaternion."
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
    seed: StateIn | None = Field(
        default=None,
        description="The state the answer is nearest (as a plan's start: values, a map or a "
        "named state); default: zeros clipped into the limits. A planar base stands where the "
        "seed puts it.",
    )
    avoid_collisions: bool = Field(
        default=True,
        description="The answer is free of the robot's current scene and of self-collision.",
    )
    move_base: bool = Field(default=False, description="A planar base may move too.")
    budget_s: FiniteFloat = Field(
        default=IK_BUDGET_S, gt=0, le=IK_BUDGET_MAX_S, description="Time budget (s)."
    )
    solutions: int = Field(
        default=3,
        ge=1,
        le=MAX_SOLUTIONS,
        description="States reaching the pose to find (from the seed, cached states, random "
        "restarts) before answering the valid one nearest the seed.",
    )


IK_EXAMPLES: list[Any] = [
    {
        "status": "success",
        "state": [0.02, -0.61, 0.01, -2.21, 0.0, 1.6, 0.8],
        "state_names": [f"panda_joint{k}" for k in range(1, 8)],
        "link": "panda_hand",
        "position_error": 0.0002,
        "orientation_error": 0.001,
        "solutions": 3,
        "rejected": 0,
        "attempts": 4,
        "message": "",
        "timings_ms": {"db": 0.4, "solve": 1.2, "total": 1.7},
    },
    {
        "status": "not_found",
        "state": None,
        "state_names": [f"panda_joint{k}" for k in range(1, 8)],
        "link": "panda_hand",
        "position_error": None,
        "orientation_error": None,
        "solutions": 0,
        "rejected": 0,
        "attempts": 113,
        "message": "no state reaches the pose of 'panda_hand' within 0.001 m and 0.01 rad in "
        "the budget (113 attempts)",
        "timings_ms": {"db": 0.4, "solve": 50.1, "total": 50.6},
    },
]


class IkResponse(BaseModel):
    """The state that puts the link at the pose, or a status saying why there is none."""

    model_config = ConfigDict(json_schema_extra={"examples": IK_EXAMPLES})

    status: Literal["success", "not_found", "in_collision"] = Field(
        description="'not_found': nothing reached the pose within the budget; 'in_collision': "
        "states reached it, all in collision."
    )
    state: list[float] | None = Field(description="In the model's `state_names` order.")
    state_names: list[str]
    link: str = Field(description="The link that was posed.")
    position_error: float | None = Field(description="Of the answer (m), by the solver's FK.")
    orientation_error: float | None = Field(description="Of the answer (rad).")
    solutions: int = Field(
        description="States found that reach the pose; the answer is the valid one nearest the "
        "seed among them."
    )
    rejected: int = Field(description="Of them, those checked and found in collision.")
    attempts: int
    message: str = ""
    timings_ms: dict[str, float] = Field(description="db, solve and total (ms).")
