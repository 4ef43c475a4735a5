"""A checked planning query: endpoints in limits and clear of obstacles, with the state
space to plan in (`planning.space`) and its motion checker (`planning.motion`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from trajcache.geometry.collision.checker import COLLIDING, FREE
from trajcache.geometry.errors import StateError
from trajcache.geometry.model.kinematics import check_limits, check_states
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import base_is_still
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import Resolution
from trajcache.planning.motion import CERTIFIABLE_CLEARANCE_M, MotionChecker
from trajcache.planning.problem import PlannerStatus, PlanResult
from trajcache.planning.space import StateSpaceSpec, state_space_spec


@dataclass(eq=False)
class Query:
    """A checked planning query: endpoints, the bounds to plan in and the collision checker."""

    start: FloatArray
    goal: FloatArray
    spec: StateSpaceSpec
    checker: MotionChecker
    base_still: bool


def prepare_query(
    model: RobotModel,
    scene: Scene,
    start: Sequence[float] | FloatArray,
    goal: Sequence[float] | FloatArray,
    *,
    resolution: Resolution | None = None,
    hold_still_base: bool = True,
) -> Query | PlanResult:
    """Check the endpoints (length, limits, collisions) and build the space to plan in.

    Returns a PlanResult (INVALID_START / INVALID_GOAL) when an endpoint is unusable. When the
    base does not move between start and goal it is held there (`hold_still_base`).
    """
    ends: list[FloatArray] = []
    for name, state, bad in (
        ("start", start, PlannerStatus.INVALID_START),
        ("goal", goal, PlannerStatus.INVALID_GOAL),
    ):
        try:
            arr = check_states(model, state, name=name)[0]
            check_limits(model, arr, name=name)
        except StateError as exc:
            return PlanResult(bad, message=str(exc))
        ends.append(arr)
    s, g = ends
    still = hold_still_base and base_is_still(s, g, model.base)
    spec = state_space_spec(
        model, scene, hold_base=s if still else None, around=(s, g), resolution=resolution
    )
    checker = MotionChecker(spec, scene)
    status = checker.clearance_status(np.stack([s, g]), CERTIFIABLE_CLEARANCE_M)
    for k, (name, bad) in enumerate(
        (("start", PlannerStatus.INVALID_START), ("goal", PlannerStatus.INVALID_GOAL))
    ):
        if status[k] == COLLIDING:
            contacts = checker.checker.state_contacts(ends[k])
            text = "; ".join(c.describe() for c in contacts) or "collision"
            return PlanResult(bad, message=f"{name} is in collision: {text}")
        if status[k] != FREE:
            message = (
                f"{name} is within {CERTIFIABLE_CLEARANCE_M * 1e3:g} mm of an obstacle: "
                "no motion from it can be certified"
            )
            return PlanResult(bad, message=message)
    return Query(s, g, spec, checker, still)
