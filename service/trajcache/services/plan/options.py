"""Plan options as a caller gives them, resolved against the service settings.

An option left out takes the settings' default (`lookup_threshold`, `max_candidates`,
`plan_budget_s`, `default_planner`); one given above its limit (`lookup_threshold_max`,
`max_candidates_limit`, `plan_budget_max_s`) is refused (422), never clipped.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from trajcache.core.config import Settings
from trajcache.geometry.model.kinematics import StateInput
from trajcache.services.errors import InvalidInputError
from trajcache.services.plan.attempt import GoalPose, PlanRequest

__all__ = ["PlanOptions", "resolve_request"]


@dataclass(frozen=True)
class PlanOptions:
    """Per-request plan options; None takes the settings' default."""

    threshold: float | None = None
    max_candidates: int | None = None
    fallback: bool = True
    budget_s: float | None = None
    planner: str | None = None
    arm_only: bool = False
    lookup: bool = True


# option → (setting giving its default, setting giving its limit)
_BOUNDS = {
    "threshold": ("lookup_threshold", "lookup_threshold_max"),
    "max_candidates": ("max_candidates", "max_candidates_limit"),
    "budget_s": ("plan_budget_s", "plan_budget_max_s"),
}


def resolve_request(
    *,
    settings: Settings,
    start: StateInput,
    goal: StateInput | None,
    options: PlanOptions,
    names: Mapping[str, str] | None = None,
    goal_pose: GoalPose | None = None,
) -> PlanRequest:
    """The plan request of `options`; `names` say how the caller calls an option in errors
    (default `options.<name>`)."""

    def bounded(name: str, value: float | None) -> float:
        default, limit_name = _BOUNDS[name]
        chosen = getattr(settings, default) if value is None else value
        limit = getattr(settings, limit_name)
        if chosen > limit:
            label = (names or {}).get(name, f"options.{name}")
            raise InvalidInputError(f"{label}: {chosen} is above {limit_name}={limit}")
        return float(chosen)

    return PlanRequest(
        start=start,
        goal=goal,
        threshold=bounded("threshold", options.threshold),
        max_candidates=int(bounded("max_candidates", options.max_candidates)),
        fallback=options.fallback,
        budget_s=bounded("budget_s", options.budget_s),
        planner=options.planner or settings.default_planner,
        arm_only=options.arm_only,
        lookup=options.lookup,
        goal_pose=goal_pose,
    )
