"""POST /v1/robots/{robot_id}/plan: parse, call the plan flow, map the answer."""

from __future__ import annotations

import time
from typing import Annotated, Any, Literal

import numpy as np
import pydantic_core
from fastapi import APIRouter, Path, Response
from pydantic import BaseModel, ConfigDict, Field, field_validator
from starlette.background import BackgroundTask

from trajcache.api.bounded import BoundedBodyRoute
from trajcache.api.deps import CtxDep
from trajcache.api.quality import JointTrajectory, TimingOptions, TrajectoryQuality, answer_extras
from trajcache.api.responses import COMMON, errors
from trajcache.core.config import Settings
from trajcache.geometry.errors import GeometryError
from trajcache.geometry.model.kinematics import StateInput
from trajcache.metrics import record_plan
from trajcache.planning.problem import PLANNER_NAMES
from trajcache.services.planning import PlanAnswer, PlanRequest, plan

router = APIRouter(tags=["plan"], responses=COMMON, route_class=BoundedBodyRoute)

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]


class PlanOptions(BaseModel):
    """Per-request options; each is bounded by the service settings."""

    model_config = ConfigDict(extra="forbid")

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


class PlanBody(BaseModel):
    """A plan request: each state as values in the model's `state_names` order, as a map
    {joint name: value} (held joints may be given at their held values), or as the name of one
    of the model's named states (SRDF group states)."""

    model_config = ConfigDict(
        extra="forbid",
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
    goal: StateIn
    options: PlanOptions = Field(default_factory=PlanOptions)


class Rejection(BaseModel):
    """A cached candidate that failed validation, and why."""

    trajectory_id: int
    status: str
    reason: str


class PlanResponse(BaseModel):
    """The answer: a trajectory and where it came from, or a status saying why there is none."""

    model_config = ConfigDict(json_schema_extra={"examples": _ANSWER_EXAMPLES})

    status: Literal["success", "miss", "failure", "error"]
    source: Literal["cache", "planner"] | None
    trajectory_id: int | None
    states: list[list[float]] | None
    candidates_tried: int
    timings_ms: dict[str, float]
    message: str = ""
    rejected: list[Rejection] = []
    joint_trajectory: JointTrajectory | None = None
    quality: TrajectoryQuality | None = None


def _state(value: list[float] | dict[str, float] | str) -> StateInput:
    return np.asarray(value, dtype=float) if isinstance(value, list) else value


def _bounded(
    value: float | int | None, default: float | int, settings: Settings, name: str, setting: str
) -> float:
    """`value` (or `default`), or a 422 when it is above the limit in `settings.<setting>`."""
    chosen = default if value is None else value
    limit = getattr(settings, setting)
    if chosen > limit:
        raise GeometryError(f"options.{name}: {chosen} is above {setting}={limit}")
    return chosen


@router.post(
    "/robots/{robot_id}/plan",
    response_model=PlanResponse,
    summary="Plan from start to goal: a validated cached trajectory, or a fresh plan",
    description="Looks up cached trajectories whose start and goal are both near the request's "
    "(reversed ones included), adapts them to the exact start and goal, and validates them "
    "against the robot's current scene; when none is valid (and `options.fallback`), a planner "
    "runs in the worker pool within the time budget and what it finds is stored. States are "
    "ordered as the model's `state_names`. No path is an answer with status `miss`, `failure` "
    "or `error`, never an error status.",
    responses=errors(
        {
            404: ("Unknown robot", "robot 'robot-7' not found"),
            422: (
                "Bad state (length, NaN, limits) or start/goal in collision",
                "start state is in collision: link 'link5' hits object 'stall_2_door'",
            ),
        }
    ),
)
def plan_route(
    ctx: CtxDep, body: PlanBody, robot_id: Annotated[str, Path(max_length=128)]
) -> Response:
    """Answer a plan request from the cache or the planner."""
    s = ctx.settings
    o = body.options
    request = PlanRequest(
        start=_state(body.start),
        goal=_state(body.goal),
        threshold=_bounded(o.threshold, s.lookup_threshold, s, "threshold", "lookup_threshold_max"),
        max_candidates=int(
            _bounded(
                o.max_candidates, s.max_candidates, s, "max_candidates", "max_candidates_limit"
            )
        ),
        fallback=o.fallback,
        budget_s=_bounded(o.budget_s, s.plan_budget_s, s, "budget_s", "plan_budget_max_s"),
        planner=o.planner or s.default_planner,
        arm_only=o.match == "arm",
        lookup=o.lookup,
    )
    answer = plan(ctx=ctx, robot_id=robot_id, request=request)
    record_plan(answer)
    extras, extra_ms = answer_extras(
        ctx=ctx,
        model=answer.model,
        scene=answer.scene,
        states=answer.states,
        timing=o.timing,
        quality=o.quality,
    )
    answer.timings_ms.update(extra_ms)
    # The answer is a PlanResponse by construction: serialized once, without a second validation.
    began = time.perf_counter()
    content = pydantic_core.to_json({**_response_body(answer), **extras})
    timings = {**answer.timings_ms, "serialize": (time.perf_counter() - began) * 1e3}
    # The request's cycle ends (after the response is sent) once its bookkeeping is written.
    background = None
    if answer.record is not None:
        background = BackgroundTask(ctx.records.written, answer.record)
    return Response(
        content,
        media_type="application/json",
        headers={"server-timing": ", ".join(f"{k};dur={v:.3f}" for k, v in timings.items())},
        background=background,
    )


def _response_body(answer: PlanAnswer) -> dict[str, object]:
    """The fields of PlanResponse, from a plan answer."""
    return {
        "status": answer.status.value,
        "source": answer.source.value if answer.source else None,
        "trajectory_id": answer.trajectory_id,
        "states": answer.states.tolist() if answer.states is not None else None,
        "candidates_tried": answer.candidates_tried,
        "timings_ms": answer.timings_ms,
        "message": answer.message,
        "rejected": [
            {"trajectory_id": r["trajectory_id"], "status": r["status"], "reason": r["reason"]}
            for r in answer.rejected
        ],
    }
