"""The plan flow (paper, section 3): lookup → adapt → validate → fallback → store → answer.

`_answer` is the spine and reads top to bottom: look up candidates, validate them, answer the
first valid one; otherwise check the endpoints and answer a miss, or fall back to the planner
(`services.plan.fallback`). The planner checks the endpoints before it searches, so a fallback
without a candidate to repair leaves them to it: only when it refuses one does the service look
for the contact to name in its 422 (`check_endpoints`), which spares a planned answer building
the scene's validator and checking both ends twice (1 ms of an MBM answer).

Each step takes the request's :class:`PlanAttempt` (`services.plan.attempt`), which holds what
the steps share and times each phase. A robot that never uploaded a scene is planned in the
empty world and its answer says so in `warnings` (under `require_scene` it is refused).

A cache hit, the hot path, reads the database once: the robot with its current scene version
(parsed scenes are cached by hash), and in the same query the replica sync (what other replicas
stored or deleted since the last sync; with `index_sync_interval_s=0` a sync that began after the
request arrived). These reads run on a Core connection of their own (`PlanAttempt.reads`), not in
the request's ORM session, whose transaction bookkeeping cost more than the query itself.
Candidates' key states come from a per-process cache (stored states never change), and so do
their ranking facts while less than a second old (`services.bookkeeping.ranking_facts`). The reads
end before validation, so no connection is held while checking collisions.

Validation memo (`cache.memo`). A cached trajectory's verdict depends on its key states, the
robot model (id = content hash of the robot), the scene (hash = content hash of every object and
environment value) and the validator's settings (its `settings_key`): the memo scope. Per
scope, a bounded per-process LRU holds digests of exact key-state sequences that passed certified
validation. Adaptation (`cache.adapt`) replaces the first and last states (their heading unwrapped
towards their neighbour) and, when the base stays still, re-anchors every interior base pose to
the request's. Validation certifies each straight segment between key states on its own, so:

- the exact adapted path was certified in this scope → valid without collision checks;
- its interior (all but the first and last state) was → only the first and last segments, the
  ones endpoint substitution changed, are validated;
- anything else — another scene (new hash), other settings, an interior moved by re-anchoring
  the base, reversal — is a different digest, and the whole path is validated.

Only a path that passed is ever remembered; a rejection is never remembered, and a memo entry can
only skip checks whose outcome is already known to be "valid". Candidates that adapt to the same
path as one already rejected in this request (two-state trajectories all become the straight
line from start to goal) reuse that verdict.

What every answer leaves behind (usage counters of the served and the rejected candidates, the
plan event, its count in the Prometheus metrics) is one `PlanOutcome` handed to
`services.bookkeeping.outcomes` (`services.plan.answers` builds it), so robots' requests and
seed jobs' are counted alike. The record goes to `ctx.records` (`services.bookkeeping.records`),
the only writer of those counters and events: written in order by a background writer, many per
transaction, flushed at shutdown. The HTTP layer keeps the request's cycle open, after sending
the answer, until its record is committed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import sqlalchemy as sa
from sqlalchemy import Connection
from sqlalchemy.orm import Session

from trajcache.cache.adapt import adapt_trajectory
from trajcache.cache.index import Match
from trajcache.cache.memo import MemoUse, proved_first
from trajcache.cache.ranking import RANKING_COLUMNS, facts_from_row, rank_matches
from trajcache.db.models import Trajectory, utcnow
from trajcache.geometry.model.kinematics import (
    StateInput,
    check_limits,
    check_states,
    resolve_state,
)
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.space import base_is_still
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.scene.variant import model_in_scene
from trajcache.services.bookkeeping.answer_quality import AnswerExtras
from trajcache.services.bookkeeping.outcomes import Requester
from trajcache.services.bookkeeping.rejections import RejectedCandidate
from trajcache.services.catalog.models import get_model
from trajcache.services.catalog.robots import robot_scene
from trajcache.services.context import ServiceContext
from trajcache.services.errors import SceneRequiredError
from trajcache.services.plan.answers import answer_hit, answer_without_path, describe_answer
from trajcache.services.plan.attempt import (
    GoalPose,
    Origin,
    PhaseClock,
    PlanAnswer,
    PlanAttempt,
    PlanRequest,
    PlanSource,
    PlanStatus,
)
from trajcache.services.plan.certified import validate_candidate
from trajcache.services.plan.fallback import check_endpoints, plan_fallback
from trajcache.services.plan.options import PlanOptions, resolve_request
from trajcache.services.plan.pose_goal import resolve_pose_goal
from trajcache.services.plan.repair import repair_candidate

__all__ = [
    "NO_SCENE_WARNING",
    "AnswerExtras",
    "PlanAnswer",
    "PlanOptions",
    "PlanRequest",
    "PlanSource",
    "PlanStatus",
    "answer_plan",
    "answer_request",
    "plan",
    "plan_in_scene",
]


NO_SCENE_WARNING = "no scene uploaded: checked for self-collision only"


@dataclass(frozen=True)
class _Hit:
    """A cached candidate that passed validation, adapted to the request."""

    match: Match
    states: np.ndarray
    memo: MemoUse


def answer_plan(
    *,
    ctx: ServiceContext,
    robot_id: str,
    start: StateInput,
    goal: StateInput | None,
    options: PlanOptions,
    extras: AnswerExtras,
    goal_pose: GoalPose | None = None,
) -> PlanAnswer:
    """The plan endpoint's request: options resolved against the settings, answered with extras;
    the goal is a state, or else `goal_pose`."""
    request = resolve_request(
        settings=ctx.settings, start=start, goal=goal, options=options, goal_pose=goal_pose
    )
    return answer_request(ctx=ctx, robot_id=robot_id, request=request, extras=extras)


def answer_request(
    *, ctx: ServiceContext, robot_id: str, request: PlanRequest, extras: AnswerExtras
) -> PlanAnswer:
    """Answer a robot's plan request and add the extras it asks for."""
    answer, attempt = _plan_robot(ctx, robot_id, request)
    return describe_answer(
        ctx=ctx, answer=answer, model=attempt.model, scene=attempt.scene, extras=extras
    )


def plan(*, ctx: ServiceContext, robot_id: str, request: PlanRequest) -> PlanAnswer:
    """Answer one plan request of a robot, in the scene the robot last uploaded."""
    return _plan_robot(ctx, robot_id, request)[0]


def plan_in_scene(
    *,
    ctx: ServiceContext,
    caller: str,
    model_id: str,
    scene: Scene,
    request: PlanRequest,
    store_as: str = "sim",
) -> PlanAnswer:
    """Answer a plan request in a given scene (a seed job's simulated robot).

    The flow is the robots' one; `caller` is recorded in the plan event with requester
    `seed_job`, and a trajectory the planner finds is stored with source `store_as`.
    """
    clock = PhaseClock()
    with ctx.sessions() as session, ctx.engine.connect() as reads:
        with clock.measure("db"):
            _read_without_transaction(reads)
            model = get_model(session=session, registry=ctx.models, model_id=model_id)
        origin = Origin(store_as, None, real=False, requester=Requester.SEED_JOB)
        attempt = _open(ctx, (session, reads), caller, origin, model, scene, request, clock)
        return _answer(attempt)


def _plan_robot(
    ctx: ServiceContext, robot_id: str, request: PlanRequest
) -> tuple[PlanAnswer, PlanAttempt]:
    """A robot's request in its current scene: one query for the robot, its scene and the sync."""
    clock = PhaseClock()
    with ctx.sessions() as session, ctx.engine.connect() as reads:
        with clock.measure("db"):
            _read_without_transaction(reads)
            robot = robot_scene(  # one query, the replica sync riding along
                session=reads,
                scenes=ctx.scenes,
                robot_id=robot_id,
                read_fn=functools.partial(ctx.indexes.read_with_sync, reads, arrived=clock.arrived),
            )
            model = get_model(session=session, registry=ctx.models, model_id=robot.model_id)
        if robot.version == 0 and ctx.settings.require_scene:
            raise SceneRequiredError(
                f"robot {robot_id!r} has no scene: upload one (PUT /v1/robots/{robot_id}/scene, "
                "an empty one if its world is empty) before planning; require_scene is on"
            )
        origin = Origin(
            "planner",
            robot_id,
            real=robot.kind == "real",
            held=robot.joint_values,
            scene_stored=robot.version > 0,
        )
        attempt = _open(ctx, (session, reads), robot_id, origin, model, robot.scene, request, clock)
        answer = _answer(attempt)
        if request.goal_pose is not None:
            answer.timings_ms["pose_goal"] = round(attempt.pose_goal_ms, 3)
            if attempt.goal_found_by is not None:
                answer.goal_state, answer.goal_found_by = attempt.goal, attempt.goal_found_by
        if robot.version == 0:
            answer.warnings.append(NO_SCENE_WARNING)
        return answer, attempt


def _open(
    ctx: ServiceContext,
    db: tuple[Session, Connection],  # the request's session, and its reads' connection
    caller: str,
    origin: Origin,
    model: RobotModel,
    scene: Scene,
    request: PlanRequest,
    clock: PhaseClock,
) -> PlanAttempt:
    """The attempt of `request`, its start and goal resolved and checked (timed as validation)."""
    with clock.measure("validate"):
        # Checked as the robot holds its joints in this scene; cached under the registered model.
        checked = model_in_scene(model, scene, origin.held, cache=ctx.variants)
        start_values = resolve_state(checked, request.start, name="start")
        # a pose goal's state is found first thing (`_answer`); the start stands in till then
        goal_in = request.start if request.goal is None else request.goal
        goal_values = resolve_state(checked, goal_in, name="goal")
        start = check_states(model, start_values, name="start")[0]
        goal = check_states(model, goal_values, name="goal")[0]
        check_limits(model, start, name="start")
        check_limits(model, goal, name="goal")
    return PlanAttempt(ctx, *db, caller, origin, model, scene, request, clock, checked, start, goal)


def _answer(attempt: PlanAttempt) -> PlanAnswer:
    """Lookup → validate → the hit; else endpoints checked → a miss, or the planner's answer.
    A pose goal is resolved to a state first (`services.plan.pose_goal`, timed as lookup)."""
    if attempt.request.goal_pose is not None:
        began = attempt.clock.seconds("lookup")
        with attempt.clock.measure("lookup"):
            found = resolve_pose_goal(attempt, attempt.request.goal_pose)
        attempt.pose_goal_ms = (attempt.clock.seconds("lookup") - began) * 1e3
        if found.state is None:
            return answer_without_path(attempt, PlanStatus.FAILURE, found.message)
        attempt.goal, attempt.goal_found_by = found.state, found.found_by
        attempt.goal_path = found.path
    matches = lookup(attempt)
    hit = validate_candidates(attempt, matches)
    if hit is not None:
        return answer_hit(attempt, hit.match.trajectory_id, hit.states, hit.memo)
    planner = attempt.ctx.planner_pool() if attempt.request.fallback else None
    if planner is None:
        check_endpoints(attempt)
        why = "planning is off" if attempt.request.fallback else "fallback planning disabled"
        message = f"no valid cached trajectory; {why}"
        return answer_without_path(attempt, PlanStatus.MISS, message)
    if len(attempt.rejections):  # a repair keeps the request's ends: check them first
        check_endpoints(attempt)
        repaired = repair_candidate(attempt, planner)
        if repaired is not None:
            return repaired
    return plan_fallback(attempt, planner)  # it checks the ends that the planner refuses


def lookup(attempt: PlanAttempt) -> list[Match]:
    """Candidates within the threshold, ranked, the first `max_candidates`; their key states
    are read (or cached) before the reads end.

    Lookup fetches up to `ranking_pool` candidates, nearest first; ranking (`cache.ranking`:
    environment nearness, real-robot validations, failure streaks) orders them, and those this
    replica proved in the current scene go first (`cache.memo.proved_first`). A pose goal
    found from a cached path's end (`pose_goal`, step 0) takes that path first, then the
    others unranked (proved first): it was chosen for its end's nearness to the pose.
    """
    ctx, reads, clock, request = attempt.ctx, attempt.reads, attempt.clock, attempt.request
    with clock.measure("db"):
        # what other replicas wrote before the request arrived (no query if `plan` read it)
        index = ctx.indexes.index(reads, attempt.model, arrived=clock.arrived)
    with clock.measure("lookup"):
        start, goal = attempt.start, attempt.goal
        arm_only = request.arm_only and base_is_still(start, goal, attempt.model.base)
        first = attempt.goal_path if request.lookup else None  # the path a pose goal came from
        # no rule on, or a first candidate given: skip the facts query, lookup's order stands
        ranking = ctx.ranking.active and first is None
        matches: list[Match] = []
        if request.lookup:
            matches = index.query(
                start,
                goal,
                threshold=request.threshold,
                limit=max(request.max_candidates, ctx.ranking.pool if ctx.ranking.active else 0),
                arm_only=arm_only,
                goal_threshold=ctx.settings.pose_goal_threshold if attempt.goal_found_by else None,
            )
        if first is not None:
            matches = [first, *(m for m in matches if m.trajectory_id != first.trajectory_id)]
        if ranking and len(matches) > 1:
            matches = _ranked(reads, ctx, matches, attempt.scene)
        # the whole pool's states: candidates proved in this scene go first (once reads end)
        attempt.candidates = ctx.indexes.states(reads, [m.trajectory_id for m in matches])
        # End the reads: no connection is held while validating. The session has one only if
        # it read a model the registry lacked, or a pose goal's ends.
        reads.close()
        if attempt.session.in_transaction():
            attempt.session.rollback()
        if len(matches) > 1 and (scope := attempt.memo_scope) is not None:
            tail = proved_first(ctx.memo, scope, matches[bool(first) :], attempt.candidates)
            matches = matches[: bool(first)] + tail
    return matches[: request.max_candidates]


def validate_candidates(attempt: PlanAttempt, matches: list[Match]) -> _Hit | None:
    """The first candidate valid once adapted; the rejected ones are noted on the attempt."""
    attempt.tried = len(matches)
    rejections = attempt.rejections
    with attempt.clock.measure("validate"):
        for match in matches:
            stored = attempt.candidates.get(match.trajectory_id)
            if stored is None:  # deleted since the index was read
                continue
            adapted = adapt_trajectory(
                stored,
                attempt.start,
                attempt.goal,
                base=attempt.model.base,
                reverse=match.reversed,
            )
            result = rejections.verdict(adapted)  # the same path as one rejected already
            if result is None:
                result, memo_use = validate_candidate(attempt, match, adapted)
                if result.valid:
                    return _Hit(match, adapted, memo_use)
            rejections.add(RejectedCandidate(match.trajectory_id, match.reversed, adapted, result))
    attempt.ctx.facts.record(
        served=None, failed=rejections.ids(), real=False, at=attempt.ctx.records.now()
    )
    return None


def _ranked(
    reads: Connection, ctx: ServiceContext, matches: list[Match], scene: Scene
) -> list[Match]:
    """`matches` in the order the ranking rules give (facts not fresh in `ctx.facts`: one query)."""
    facts, missing = ctx.facts.get_many(m.trajectory_id for m in matches)
    if missing:
        rows = reads.execute(
            sa.select(*(getattr(Trajectory, c) for c in RANKING_COLUMNS)).where(
                Trajectory.id.in_(missing)
            )
        ).all()
        read = {row.id: facts_from_row(row) for row in rows}
        ctx.facts.put_many(read)
        facts.update(read)
    return rank_matches(matches, facts, env=scene.env, now=utcnow(), rules=ctx.ranking)


def _read_without_transaction(reads: Connection) -> None:
    """On PostgreSQL, run the lookup's reads in autocommit: no BEGIN and ROLLBACK round trips.

    Each read sees its own snapshot either way (read committed) and none writes; the connection
    goes back to the pool (its isolation level reset) when the reads end. The request's writes
    run in its session's own transaction.
    """
    if reads.dialect.name == "postgresql":
        reads.execution_options(isolation_level="AUTOCOMMIT")
