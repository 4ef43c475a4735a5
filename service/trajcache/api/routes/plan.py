"""POST /v1/robots/{robot_id}/plan: parse, call the plan flow, map the answer."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, Path
from pydantic import BaseModel, ConfigDict, Field

from trajcache.api.deps import CtxDep
from trajcache.services.planning import PlanRequest, plan

router = APIRouter(tags=["plan"])

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
    budget_s: FiniteFloat | None = Field(
        default=None, gt=0, description="Planning time budget in seconds."
    )
    planner: str | None = Field(default=None, description="Planner name (default from settings).")
    match: Literal["full", "arm"] = Field(
        default="full",
        description="'arm' matches on arm joints only when the base does not move, so a motion "
        "learned at one place serves the same motion elsewhere (validation keeps it safe).",
    )


class PlanBody(BaseModel):
    """A plan request: states ordered as the model's `state_names`."""

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

    start: list[FiniteFloat] = Field(min_length=1, max_length=64)
    goal: list[FiniteFloat] = Field(min_length=1, max_length=64)
    options: PlanOptions = Field(default_factory=PlanOptions)


class Rejection(BaseModel):
    """A cached candidate that failed validation, and why."""

    trajectory_id: int
    status: str
    reason: str


class PlanResponse(BaseModel):
    """The answer: a trajectory and where it came from, or a status saying why there is none."""

    status: Literal["success", "miss", "failure", "error"]
    source: Literal["cache", "planner"] | None
    trajectory_id: int | None
    states: list[list[float]] | None
    candidates_tried: int
    timings_ms: dict[str, float]
    message: str = ""
    rejected: list[Rejection] = []


def _bounded(
    value: float | int | None, default: float | int, limit: float | int, name: str
) -> float:
    from trajcache.geometry.errors import GeometryError

    chosen = default if value is None else value
    if chosen > limit:
        raise GeometryError(f"options.{name}={chosen} exceeds the service limit {limit}")
    return chosen


@router.post(
    "/robots/{robot_id}/plan",
    response_model=PlanResponse,
    summary="Plan from start to goal: a validated cached trajectory, or a fresh plan",
    responses={
        404: {"description": "Unknown robot"},
        422: {"description": "Bad state (length, NaN, limits) or start/goal in collision"},
        503: {"description": "Database unavailable"},
    },
)
def plan_route(
    ctx: CtxDep, body: PlanBody, robot_id: Annotated[str, Path(max_length=128)]
) -> PlanResponse:
    """Answer a plan request from the cache or the planner."""
    s = ctx.settings
    o = body.options
    request = PlanRequest(
        start=np.asarray(body.start, dtype=float),
        goal=np.asarray(body.goal, dtype=float),
        threshold=_bounded(o.threshold, s.lookup_threshold, s.lookup_threshold_max, "threshold"),
        max_candidates=int(
            _bounded(o.max_candidates, s.max_candidates, s.max_candidates_limit, "max_candidates")
        ),
        fallback=o.fallback,
        budget_s=_bounded(o.budget_s, s.plan_budget_s, s.plan_budget_max_s, "budget_s"),
        planner=o.planner or s.default_planner,
        arm_only=o.match == "arm",
    )
    answer = plan(ctx=ctx, robot_id=robot_id, request=request)
    return PlanResponse(
        status=answer.status.value,
        source=answer.source.value if answer.source else None,
        trajectory_id=answer.trajectory_id,
        states=answer.states.tolist() if answer.states is not None else None,
        candidates_tried=answer.candidates_tried,
        timings_ms=answer.timings_ms,
        message=answer.message,
        rejected=[Rejection.model_validate(r) for r in answer.rejected],
    )
