"""A goal given as a pose of a link: the goal state a plan request then goes to.

Lookup by pose first, then inverse kinematics (`geometry/model/ik.py`):

0. From the paths the lookup could take: a hit needs a cached path with an end within the
   request's threshold of its start, so their other ends are the goal states a hit can reach.
   This replica's trajectory index lists them (`TrajectoryIndex.ends_near`) without a database
   read, the NEAR_START_POOL most recently stored where more share the start (forward
   kinematics ranks them all): one that is free and reaches the pose as it is is the goal,
   else IK starts from the one whose link lies nearest the target (of the few nearest, one
   whose path this replica proved in the current scene first), its restarts and its answer
   within the pose goals' threshold of it. That path is then the lookup's first candidate
   (`PoseGoalFound.path`). Otherwise (none, IK finds nothing there, the lookup off or a
   planar base) the whole cache is searched, as follows:
1. As it is: among the ends of every cached trajectory of the model, those that put the link
   within the tolerances (read from the end-pose index, checked by forward kinematics:
   `services.ik.cached.ends_within`) and are free in the robot's scene; the one whose
   trajectory's other end is nearest the request's start is the goal. The joint lookup then
   finds that trajectory at distance zero from the goal.
2. After IK from a nearby cached state: the solver starts from the cached state whose link
   lies nearest the target (`nearest_starts`), its random restarts within the pose goals'
   lookup threshold of it (`pose_goal_threshold`), then from the others, so that a solution it
   finds lies next to a cached trajectory's end. The lookup takes a path whose goal end lies
   within that threshold (`flow.lookup`): the goal state is the service's choice, not the
   client's, and the adapted path is certified (or repaired) as any other.
3. Otherwise IK from the request's start, with random restarts (the solution nearest it).

The ends of 1 and the starts of 2 come from one read of the end-pose index while the cache is
small (`pose_ends`); how many trajectories the model has is the replica's last count, with no
sync of its own (it only chooses how to search).

A goal state found either way is a state like any other: the plan flow looks up, adapts,
validates and, on a miss, plans to it. None found is a failure answer, not an error.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from trajcache.cache.index import EndsOf, Match
from trajcache.cache.memo import is_proved
from trajcache.cache.metric import state_distance
from trajcache.geometry.model.ik import IkProblem, IkStatus, PoseTarget, solve_ik
from trajcache.geometry.model.pin_kinematics import PinKinematics
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray, pose_matrix
from trajcache.geometry.scene.fields import unit_quaternion
from trajcache.geometry.validation.validator import validator_for
from trajcache.services.catalog.models import model_source
from trajcache.services.ik.cached import PoseEnds, meets_target, pose_ends, stored_count
from trajcache.services.ik.solve import free_fn, link_of
from trajcache.services.plan.attempt import GoalPose, PlanAttempt

__all__ = ["NO_GOAL_STATE", "PoseGoalFound", "resolve_pose_goal"]

POSE_IK_BUDGET_S = 0.1  # IK's share of a plan request's time
SEED_POOL = 32  # the ends nearest the target among which IK prefers a path proved in the scene
NEAR_START_POOL = 128  # the most cached ends near the start a pose goal considers (newest)
NO_GOAL_STATE = "no goal state puts"  # how the failure message of an unreached pose begins


@dataclass(frozen=True)
class PoseGoalFound:
    """The goal state a pose goal resolved to (None: no free state reaches the pose), how it
    was found ("cached": a cached trajectory's end as it is; "ik"), why not, if not, and the
    cached path it was found from, when step 0 found it: the lookup's first candidate."""

    state: FloatArray | None
    found_by: str
    message: str = ""
    path: Match | None = None  # the cached path whose end the state was found from (step 0)


def resolve_pose_goal(attempt: PlanAttempt, goal: GoalPose) -> PoseGoalFound:
    """The goal state of `goal` for this request (module docstring)."""
    ctx, checked, session = attempt.ctx, attempt.checked, attempt.session
    source = model_source(session=session, model_id=attempt.model.model_id, registry=ctx.models)
    kinematics = ctx.kinematics.get_or_build(
        checked, lambda: PinKinematics.build(checked, source.urdf)
    )
    link = link_of(checked, source.srdf, goal.link, {"link": "goal_pose.link"})
    quaternion = unit_quaternion(list(goal.orientation), "goal_pose.orientation")
    target = PoseTarget(
        link,
        pose_matrix(list(goal.position), quaternion),
        goal.position_tolerance,
        goal.orientation_tolerance,
    )
    checker = validator_for(checked, attempt.scene, ctx.settings, cache=ctx.validators).checker
    free = free_fn(checker)
    near_start = _from_start(attempt, kinematics, target, free)
    if near_start is not None:
        return near_start
    stored = stored_count(ctx.indexes, session, attempt.model)
    ends = pose_ends(session, attempt.model, checked, target, attempt.start, stored=stored)
    as_is = _cached_as_is(attempt, ends, free)
    if as_is is not None:
        return PoseGoalFound(as_is, "cached")
    starts, window = ends.starts, ctx.settings.pose_goal_threshold
    seeds: list[tuple[FloatArray, list[FloatArray], float | None]] = [(attempt.start, starts, None)]
    if starts:  # near the nearest cached end first, where the lookup finds its path
        seeds[:0] = [(starts[0], [], window), (starts[0], starts[1:], None)]
    budget = POSE_IK_BUDGET_S / len(seeds)
    for seed, others, near in seeds:
        problem = IkProblem(
            kinematics, target, seed, starts=others, valid_fn=free, solutions=1,
            budget_s=budget, window=near,
        )  # fmt: skip
        found = solve_ik(problem)
        if found.status is IkStatus.SUCCESS and found.state is not None:
            return PoseGoalFound(found.state, "ik")
    why = "every state found that reaches it is in collision" if found.rejected else "none found"
    return PoseGoalFound(
        None,
        "ik",
        f"{NO_GOAL_STATE} {link!r} within {goal.position_tolerance:g} m and "
        f"{goal.orientation_tolerance:g} rad of the pose ({why})",
    )


def _from_start(
    attempt: PlanAttempt,
    kinematics: PinKinematics,
    target: PoseTarget,
    free: Callable[[FloatArray], bool],
) -> PoseGoalFound | None:
    """The goal state from the cached paths the lookup could take (step 0 of the module
    docstring): those with an end within the request's threshold of its start, read from this
    replica's trajectory index (no database read). Their other end, if one is free and reaches
    the pose as it is (the nearest such path first); else IK from the one whose link lies
    nearest the target, its restarts and its answer within the pose goals' threshold of it.
    None: neither."""
    checked, request = attempt.checked, attempt.request
    if checked.base is BaseType.PLANAR or not request.lookup:
        return None  # a planar base's ends stand elsewhere: the end-pose index places them
    index = attempt.ctx.indexes.index(attempt.reads, attempt.model, arrived=attempt.clock.arrived)
    ends = _newest(index.ends_near(attempt.start, threshold=request.threshold))
    if len(ends.ids) == 0:
        return None
    meets, gaps = meets_target(checked, target, ends.states)
    for k in np.flatnonzero(meets):
        if free(ends.states[k]):
            return PoseGoalFound(np.array(ends.states[k]), "cached", path=_path(ends, int(k), 0.0))
    nearest = _seed(attempt, ends, gaps)
    seed, window = ends.states[nearest], attempt.ctx.settings.pose_goal_threshold

    def near_and_free(state: FloatArray) -> bool:  # where the lookup finds the seed's path
        return bool(np.abs(state - seed).max() < window) and free(state)

    problem = IkProblem(
        kinematics, target, seed, valid_fn=near_and_free, solutions=1,
        budget_s=POSE_IK_BUDGET_S / 4, window=window,
    )  # fmt: skip
    found = solve_ik(problem)
    if found.status is IkStatus.SUCCESS and found.state is not None:
        d_base, d_arm = state_distance(found.state, seed, base=checked.base)
        return PoseGoalFound(found.state, "ik", path=_path(ends, nearest, float(d_base + d_arm)))
    return None


def _newest(ends: EndsOf) -> EndsOf:
    """The NEAR_START_POOL most recently stored of `ends` (ids grow with time), in their order:
    where more paths share the start than FK can rank in time, the robot's recent work (and
    scene) is likeliest to hold the pose; the whole cache is searched after (step 1)."""
    if len(ends.ids) <= NEAR_START_POOL:
        return ends
    keep = np.sort(np.argsort(-ends.ids, kind="stable")[:NEAR_START_POOL])
    return EndsOf(ends.ids[keep], ends.reversed[keep], ends.distances[keep], ends.states[keep])


def _seed(attempt: PlanAttempt, ends: EndsOf, gaps: FloatArray) -> int:
    """Which of `ends` IK starts from: of the SEED_POOL whose link lies nearest the target,
    the nearest whose path this replica proved in the robot's current scene (`cache.memo`),
    else the nearest. Where many paths share the start, the nearest end may be another
    scene's, whose path crosses this scene's objects."""
    order = np.argsort(gaps, kind="stable")[:SEED_POOL]
    scope = attempt.memo_scope
    if scope is None or len(order) == 1:
        return int(order[0])
    for part in (order[:1], order[1:]):  # the nearest alone first: usually it is the one
        stored = attempt.ctx.indexes.states(attempt.reads, [int(ends.ids[k]) for k in part])
        for k in part:
            if is_proved(attempt.ctx.memo, scope, stored.get(int(ends.ids[k])), ends.reversed[k]):
                return int(k)
    return int(order[0])


def _path(ends: EndsOf, k: int, d_goal: float) -> Match:
    """The lookup's match of the k-th entry of `ends` for a goal `d_goal` from its other end."""
    d_start = float(ends.distances[k])
    return Match(int(ends.ids[k]), bool(ends.reversed[k]), d_start, d_goal, d_start + d_goal)


def _cached_as_is(
    attempt: PlanAttempt, found: PoseEnds, free: Callable[[FloatArray], bool]
) -> FloatArray | None:
    """The cached end state within the tolerances, free, whose trajectory's other end is
    nearest the request's start."""
    if attempt.checked.base is BaseType.PLANAR:
        return None  # a planar base's cached ends stand elsewhere: IK places the arm
    ends = found.within
    if len(ends.gaps) == 0:
        return None
    order = np.argsort(np.linalg.norm(ends.partners - attempt.start, axis=1), kind="stable")
    for k in order:
        if free(ends.states[k]):
            return np.array(ends.states[k])
    return None
