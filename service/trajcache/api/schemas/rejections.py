"""Why a cached candidate was rejected, as a plan event records it."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

_STATE = [1.375, 1.3, 1.5708, 0.0, -1.1, 0.0, 1.1, 0.0, 1.7, 0.0]
REJECTED_EXAMPLE: dict[str, Any] = {
    "trajectory_id": 4207,
    "reversed": False,
    "status": "collision",
    "reason": "link 'link5' hits object 'stall_2_door'",
    "start": [1.375, 1.3, 1.5708, 0, -1.3, 0, 0.8, 0, 2.1, 0],
    "goal": [1.375, 1.3, 1.5708, 0, -0.876, 0, 1.483, 0, 1.252, 0],
    "sample": 14,
    "at": 0.0,
    "samples": 32,
    "segment": 0,
    "state": _STATE,
    "pairs": [{"link": "link5", "other": "stall_2_door", "kind": "scene"}],
    "joints": [],
    "held": {},
}


class ContactPairOut(BaseModel):
    """A link and what it touches: a scene object (`scene`) or another link (`self`)."""

    link: str
    other: str
    kind: Literal["scene", "self"]


class RejectedCandidateOut(BaseModel):
    """A cached candidate that failed validation, and where: its first failing sample."""

    model_config = ConfigDict(json_schema_extra={"examples": [REJECTED_EXAMPLE]})

    trajectory_id: int
    reversed: bool = Field(description="The candidate was played backwards (a B→A path for A→B).")
    status: Literal["collision", "out_of_limits", "too_close"]
    reason: str
    start: list[float] = Field(description="The request's start: the candidate's first state.")
    goal: list[float] = Field(description="The request's goal: the candidate's last state.")
    sample: int | None = Field(
        default=None,
        description="Index of the validation sample at (or just before) the failing state.",
    )
    at: float | None = Field(
        default=None,
        description="Fraction of the step from `sample` to the next one where it failed (0: at "
        "the sample itself; certification finds contact between samples too).",
    )
    samples: int | None = Field(default=None, description="Validation samples of the path.")
    segment: int | None = Field(
        default=None, description="Segment of the path (between key states k and k + 1)."
    )
    state: list[float] | None = Field(default=None, description="The configuration that failed.")
    pairs: list[ContactPairOut] = Field(
        default_factory=list,
        description="Every pair in contact there (a collision), or the pairs too close to "
        "certify (too_close).",
    )
    joints: list[str] = Field(default_factory=list, description="Joints out of their limits.")
    held: dict[str, float] | None = Field(
        default=None,
        description="The joint values the robot held outside the planning joints when the "
        "candidate was validated (`{}`: its model's); the 3D view poses the links with them.",
    )
