"""The plan flow (paper, section 3): lookup → adapt → validate → fallback → store → answer.

A cache hit, the hot path, reads the database once: the robot with its current scene version
(parsed scenes are cached by hash), and in the same query the replica sync (what other replicas
stored or deleted since the last sync; with `index_sync_interval_s=0` a sync that began after the
request arrived).
Candidates' key states come from a per-process cache (stored states never change), and so do
their ranking facts while less than a second old (`services.ranking_facts`). The read
transaction ends before validation, so no connection is held while checking collisions.

Validation memo (`cache.memo`). A cached trajectory's verdict depends on its key states, the
robot model (id = content hash of the robot), the scene (hash = content hash of every object and
environment value) and the validator's settings (steps, certified mode): the memo scope. Per
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

Bookkeeping of a hit (usage counters of the served and the rejected candidates, the plan event)
goes to `ctx.records` (`services.plan_records`): written in order by a background writer, many per
transaction, flushed at shutdown. The HTTP layer keeps the request's cycle open, after sending the
answer, until its record is committed.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.cache.adapt import adapt_trajectory, base_is_still
from trajcache.cache.index import Match
from trajcache.cache.memo import MemoScope, MemoUse, validate_with_memo
from trajcache.cache.ranking import RANKING_COLUMNS, facts_from_row, rank_matches
from trajcache.db.models import PlanEvent, Trajectory, utcnow
from trajcache.geometry.errors import CollisionStateError
from trajcache.geometry.model.kinematics import (
    StateInput,
    check_limits,
    check_states,
    resolve_state,
)
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.scene import Scene, scene_to_payload
from trajcache.geometry.scene.variant import model_in_scene
from trajcache.geometry.validation.validator import (
    ValidationResult,
    ValidationSettings,
    validator_for,
)
from trajcache.jobs.pool import PlannerPool
from trajcache.planning.problem import PlannerStatus, PlanningProblem, SceneSource, fresh_seed
from trajcache.services.context import ServiceContext
from trajcache.services.errors import UnavailableError
from trajcache.services.models import get_model, model_source
from trajcache.services.plan_records import PlanRecord, QualityJob
from trajcache.services.robots import robot_scene
from trajcache.services.trajectories import quality_columns, store_trajectory


class PlanStatus(str, Enum):
    """How a plan request ended."""

    SUCCESS = "success"
    MISS = "miss"  # no valid cached candidate and no fallback planning asked for or available
    FAILURE = "failure"  # the planner found no path within its budget
    ERROR = "error"  # the planner could not run (pool broken, backend down): answered with 503


class PlanSource(str, Enum):
    """Where an answered trajectory came from."""

    CACHE = "cache"
    PLANNER = "planner"


@dataclass(frozen=True)
class PlanRequest:
    """A validated plan request with its options resolved against the settings."""

    start: StateInput  # values in state_names order, a {joint: value} map, or a named state
    goal: StateInput
    threshold: float
    max_candidates: int
    fallback: bool = True
    budget_s: float = 2.0
    planner: str = "rrtconnect"
    arm_only: bool = False  # match on arm joints only when the base does not move
    lookup: bool = True  # False: skip the cache and plan (a fresh plan is still stored)


@dataclass(frozen=True)
class _Origin:
    """Where a request comes from: what a planned trajectory is stored as, and if it is real."""

    store_source: str  # source of a trajectory the planner finds for this request
    store_robot_id: str | None
    real: bool  # a real robot: a hit counts as a validation of the trajectory in the real world
    held: Mapping[str, float] | None = None  # the robot's own held joint values, if it set any


@dataclass
class PlanAnswer:
    """What the plan endpoint returns."""

    status: PlanStatus
    source: PlanSource | None
    trajectory_id: int | None
    states: np.ndarray | None
    candidates_tried: int
    timings_ms: dict[str, float]
    message: str = ""
    rejected: list[dict[str, object]] = field(default_factory=list)
    record: int | None = None  # sequence number of the bookkeeping in `ctx.records`, if queued
    memo: MemoUse | None = None  # how the served cached trajectory was validated
    # What the answer was planned and validated in, so its extras (quality, timing) need not
    # read the robot again; set by `plan` and `plan_in_scene`.
    model: RobotModel | None = None
    scene: Scene | None = None


@dataclass
class _Clock:
    began: float = field(default_factory=time.perf_counter)
    arrived: float = field(default_factory=time.monotonic)  # what replica syncs must cover
    lookup: float = 0.0
    validate: float = 0.0
    plan: float = 0.0
    db: float = 0.0

    def timings(self) -> dict[str, float]:
        total = (time.perf_counter() - self.began) * 1e3
        return {
            "lookup": round(self.lookup * 1e3, 3),
            "validate": round(self.validate * 1e3, 3),
            "plan": round(self.plan * 1e3, 3),
            "db": round(self.db * 1e3, 3),
            "total": round(total, 3),
        }


def plan(*, ctx: ServiceContext, robot_id: str, request: PlanRequest) -> PlanAnswer:
    """Answer one plan request of a robot, in the scene the robot last uploaded."""
    clock = _Clock()
    with ctx.sessions() as session:
        t = time.perf_counter()
        _read_without_transaction(session)
        robot = robot_scene(  # one query, the replica sync riding along
            session=session,
            scenes=ctx.scenes,
            robot_id=robot_id,
            read_fn=functools.partial(ctx.indexes.read_with_sync, session, arrived=clock.arrived),
        )
        model = get_model(session=session, registry=ctx.models, model_id=robot.model_id)
        scene = robot.scene
        clock.db += time.perf_counter() - t
        origin = _Origin("planner", robot_id, real=robot.kind == "real", held=robot.joint_values)
        answer = _plan_in_scene(session, ctx, robot_id, model, scene, request, origin, clock)
    answer.model, answer.scene = model, scene
    return answer


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

    The flow is the robots' one; `caller` is recorded in the plan event, and a trajectory the
    planner finds is stored with source `store_as`.
    """
    clock = _Clock()
    with ctx.sessions() as session:
        t = time.perf_counter()
        model = get_model(session=session, registry=ctx.models, model_id=model_id)
        clock.db += time.perf_counter() - t
        origin = _Origin(store_as, None, real=False)
        answer = _plan_in_scene(session, ctx, caller, model, scene, request, origin, clock)
    answer.model, answer.scene = model, scene
    return answer


def _plan_in_scene(
    session: Session,
    ctx: ServiceContext,
    robot_id: str,
    model: RobotModel,
    scene: Scene,
    request: PlanRequest,
    origin: _Origin,
    clock: _Clock,
) -> PlanAnswer:
    """Lookup → rank → adapt → validate → (fallback → store) → answer, in one session.

    Lookup fetches up to `ranking_pool` candidates within the threshold, nearest first; ranking
    (`cache.ranking`: environment nearness, real-robot validations, failure streaks) orders them
    and the first `max_candidates` are tried.
    """
    t = time.perf_counter()
    # Checked as the robot holds its joints in this scene; cached under the registered model.
    checked = model_in_scene(model, scene, origin.held)
    start_values = resolve_state(checked, request.start, name="start")
    goal_values = resolve_state(checked, request.goal, name="goal")
    start = check_states(model, start_values, name="start")[0]
    goal = check_states(model, goal_values, name="goal")[0]
    check_limits(model, start, name="start")
    check_limits(model, goal, name="goal")
    clock.db += time.perf_counter() - t

    t = time.perf_counter()
    # what other replicas wrote before the request arrived (no query if `plan` read it already)
    index = ctx.indexes.index(session, model, arrived=clock.arrived)
    clock.db += time.perf_counter() - t

    t = time.perf_counter()
    arm_only = request.arm_only and base_is_still(start, goal, arm_offset=model.arm_offset)
    ranking = ctx.ranking.active  # no rule on: skip the facts query, lookup's order stands
    matches: list[Match] = []
    if request.lookup:
        matches = index.query(
            start,
            goal,
            threshold=request.threshold,
            limit=max(request.max_candidates, ctx.ranking.pool if ranking else 0),
            arm_only=arm_only,
        )
    if ranking and len(matches) > 1:
        matches = _ranked(session, ctx, matches, scene)
    matches = matches[: request.max_candidates]
    candidates = ctx.indexes.states(session, [m.trajectory_id for m in matches])
    session.rollback()  # end the read transaction: no connection is held while validating
    clock.lookup += time.perf_counter() - t

    t = time.perf_counter()
    validator = validator_for(checked, scene, ctx.settings)
    scope = memo_scope(checked, scene, ctx.settings)
    failed: list[int] = []
    rejected: list[dict[str, object]] = []
    seen: list[tuple[np.ndarray, ValidationResult]] = []  # adapted paths rejected so far
    for match in matches:
        stored = candidates.get(match.trajectory_id)
        if stored is None:  # deleted since the index was read
            continue
        adapted = adapt_trajectory(
            stored, start, goal, arm_offset=model.arm_offset, reverse=match.reversed
        )
        result = next((r for path, r in seen if np.array_equal(path, adapted)), None)
        if result is None:
            result, memo_use = validate_with_memo(
                adapted, validate_fn=validator.validate, memo=ctx.memo, scope=scope
            )
            if result.valid:
                clock.validate += time.perf_counter() - t
                return _answer_hit(
                    ctx, robot_id, origin, model, scene, match, adapted, failed, rejected, clock,
                    memo_use,
                )  # fmt: skip
            seen.append((adapted, result))
        failed.append(match.trajectory_id)
        rejected.append(_rejection(match, result))
    clock.validate += time.perf_counter() - t
    ctx.facts.record(served=None, failed=failed, real=False, at=utcnow())

    _raise_if_endpoint_collides(validator, start, goal)
    planner = ctx.planner_pool() if request.fallback else None
    if planner is None:
        why = "fallback planning disabled" if not request.fallback else "planning is off"
        return _answer_without_path(
            session,
            robot_id,
            model,
            scene,
            PlanStatus.MISS,
            len(matches),
            failed,
            rejected,
            clock,
            f"no valid cached trajectory; {why}",
        )
    return _plan_fallback(
        session,
        ctx,
        planner,
        origin,
        robot_id,
        model,
        scene,
        start,
        goal,
        request,
        len(matches),
        failed,
        rejected,
        clock,
    )


def _ranked(
    session: Session, ctx: ServiceContext, matches: list[Match], scene: Scene
) -> list[Match]:
    """`matches` in the order the ranking rules give (facts not fresh in `ctx.facts`: one query)."""
    facts, missing = ctx.facts.get_many(m.trajectory_id for m in matches)
    if missing:
        rows = session.execute(
            sa.select(*(getattr(Trajectory, c) for c in RANKING_COLUMNS)).where(
                Trajectory.id.in_(missing)
            )
        ).all()
        read = {row.id: facts_from_row(row) for row in rows}
        ctx.facts.put_many(read)
        facts.update(read)
    return rank_matches(matches, facts, env=scene.env, now=utcnow(), rules=ctx.ranking)


def _read_without_transaction(session: Session) -> None:
    """On PostgreSQL, run the lookup's reads in autocommit: no BEGIN and ROLLBACK round trips.

    Each read sees its own snapshot either way (read committed) and none writes; the connection
    goes back to the pool (its isolation level reset) when the reads end, so later writes of the
    request run in an ordinary transaction.
    """
    if session.get_bind().dialect.name == "postgresql":
        session.connection(execution_options={"isolation_level": "AUTOCOMMIT"})


def memo_scope(model: RobotModel, scene: Scene, settings: ValidationSettings) -> MemoScope | None:
    """What a validation verdict depends on besides the states (None: scene has no hash).

    The same inputs `validator_for` builds its validator from; a setting added there belongs here.
    """
    if not scene.hash:
        return None
    resolution = (settings.step_position_m, settings.step_orientation_rad, settings.step_joint_rad)
    return MemoScope(model.model_id, scene.hash, (*resolution, settings.certified_validation))


def _rejection(match: Match, result: ValidationResult) -> dict[str, object]:
    return {
        "trajectory_id": match.trajectory_id,
        "status": result.status.value,
        "reason": result.message,
    }


def _raise_if_endpoint_collides(validator: object, start: np.ndarray, goal: np.ndarray) -> None:
    """A start or goal in collision is the caller's error (422), not a planning failure."""
    checker = validator.checker  # type: ignore[attr-defined]
    for name, state in (("start", start), ("goal", goal)):
        contacts = checker.state_contacts(state)
        if contacts:
            text = "; ".join(c.describe() for c in contacts)
            raise CollisionStateError(f"{name} state is in collision: {text}", contacts=contacts)


def _record_usage(session: Session, hit: int | None, failed: list[int]) -> None:
    now = utcnow()
    if hit is not None:
        session.execute(
            sa.update(Trajectory)
            .where(Trajectory.id == hit)
            .values(
                hits=Trajectory.hits + 1,
                consecutive_failures=0,
                last_used_at=now,
                last_validated_at=now,
            )
        )
    if failed:  # row by row in id order, as the plan-record writer locks them: no deadlock
        session.connection().execute(_FAILED_ONE, [{"b_id": i} for i in sorted(set(failed))])


_FAILED_ONE = (
    sa.update(Trajectory)
    .where(Trajectory.id == sa.bindparam("b_id"))
    .values(
        failures=Trajectory.failures + 1,
        consecutive_failures=Trajectory.consecutive_failures + 1,
    )
)


def _event(
    robot_id: str,
    model: RobotModel,
    scene: Scene,
    status: PlanStatus,
    source: PlanSource | None,
    trajectory_id: int | None,
    tried: int,
    timings: dict[str, float],
    error: str | None = None,
    seed: int | None = None,
) -> PlanEvent:
    return PlanEvent(
        **_event_values(
            robot_id, model, scene, status, source, trajectory_id, tried, timings, error, seed
        )
    )


def _event_values(
    robot_id: str,
    model: RobotModel,
    scene: Scene,
    status: PlanStatus,
    source: PlanSource | None,
    trajectory_id: int | None,
    tried: int,
    timings: dict[str, float],
    error: str | None = None,
    seed: int | None = None,  # the planner's seed, when the request planned
) -> dict[str, object]:
    return {
        "robot_id": robot_id,
        "model_id": model.model_id,
        "scene_hash": scene.hash,
        "status": status.value,
        "source": source.value if source else None,
        "trajectory_id": trajectory_id,
        "candidates_tried": tried,
        "lookup_ms": timings["lookup"],
        "validate_ms": timings["validate"],
        "plan_ms": timings["plan"],
        "total_ms": timings["total"],
        "error": (error or None) and error[:500],
        "seed": seed,
    }


def _answer_hit(
    ctx: ServiceContext,
    robot_id: str,
    origin: _Origin,
    model: RobotModel,
    scene: Scene,
    match: Match,
    states: np.ndarray,
    failed: list[int],
    rejected: list[dict[str, object]],
    clock: _Clock,
    memo_use: MemoUse,
) -> PlanAnswer:
    """Answer with a validated cached trajectory; its bookkeeping is queued, not awaited."""
    tried = len(failed) + 1
    timings = clock.timings()
    event = _event_values(
        robot_id, model, scene, PlanStatus.SUCCESS, PlanSource.CACHE, match.trajectory_id,
        tried, timings,
    )  # fmt: skip
    now = utcnow()
    record = ctx.records.submit(
        PlanRecord(now, match.trajectory_id, tuple(failed), event, real=origin.real)
    )
    ctx.facts.record(served=match.trajectory_id, failed=failed, real=origin.real, at=now)
    return PlanAnswer(
        PlanStatus.SUCCESS,
        PlanSource.CACHE,
        match.trajectory_id,
        states,
        tried,
        timings,
        rejected=rejected,
        record=record,
        memo=memo_use,
    )


def _answer_without_path(
    session: Session,
    robot_id: str,
    model: RobotModel,
    scene: Scene,
    status: PlanStatus,
    tried: int,
    failed: list[int],
    rejected: list[dict[str, object]],
    clock: _Clock,
    message: str,
    seed: int | None = None,
) -> PlanAnswer:
    t = time.perf_counter()
    _record_usage(session, None, failed)
    timings = clock.timings()
    session.add(_event(robot_id, model, scene, status, None, None, tried, timings, message, seed))
    session.commit()
    clock.db += time.perf_counter() - t
    return PlanAnswer(status, None, None, None, tried, clock.timings(), message, rejected)


def _plan_fallback(
    session: Session,
    ctx: ServiceContext,
    planner: PlannerPool,
    origin: _Origin,
    robot_id: str,
    model: RobotModel,
    scene: Scene,
    start: np.ndarray,
    goal: np.ndarray,
    request: PlanRequest,
    tried: int,
    failed: list[int],
    rejected: list[dict[str, object]],
    clock: _Clock,
) -> PlanAnswer:
    """Plan in the worker pool, validate like a cached trajectory, store and answer.

    The session's transaction ends before planning, so a request waiting on a worker holds no
    database connection; storing the result and the usage opens a new one. Each request plans
    with a fresh seed (a retry searches anew), recorded in its plan event.
    """
    t = time.perf_counter()
    problem = PlanningProblem(
        model=model_source(session=session, model_id=model.model_id, registry=ctx.models),
        scene=SceneSource(hash=scene.hash, payload=scene_to_payload(scene)),
        start=tuple(float(v) for v in start),
        goal=tuple(float(v) for v in goal),
        budget_s=request.budget_s,
        planner=request.planner,
        seed=fresh_seed(),
        joint_values=tuple(sorted((origin.held or {}).items())),
        step_position_m=ctx.settings.step_position_m,  # the worker certifies as we validate
        step_orientation_rad=ctx.settings.step_orientation_rad,
        step_joint_rad=ctx.settings.step_joint_rad,
        certified_validation=ctx.settings.certified_validation,
    )
    session.rollback()  # nothing is written yet; release the connection while planning
    outcome = planner.submit(problem)
    clock.plan += time.perf_counter() - t
    # A coalesced or remembered answer ran with its leader's seed; an unrun one with none.
    seed = outcome.seed if outcome.seed is not None else problem.seed
    if not outcome.solved or outcome.path is None:
        status = PlanStatus.ERROR if outcome.status is PlannerStatus.ERROR else PlanStatus.FAILURE
        message = f"{outcome.status.value}: {outcome.message}".rstrip(": ")
        answer = _answer_without_path(
            session, robot_id, model, scene, status, tried, failed, rejected, clock, message, seed
        )
        if status is PlanStatus.ERROR:  # the planner could not run: a 503 the caller may retry
            raise UnavailableError(f"planning is unavailable, retry later ({outcome.message})")
        return answer
    t = time.perf_counter()
    checked = model_in_scene(model, scene, origin.held)
    result = validator_for(checked, scene, ctx.settings).validate(outcome.path)
    clock.validate += time.perf_counter() - t
    if not result.valid:
        return _answer_without_path(
            session,
            robot_id,
            model,
            scene,
            PlanStatus.FAILURE,
            tried,
            failed,
            rejected,
            clock,
            f"planned path failed validation: {result.message}",
            seed,
        )
    t = time.perf_counter()
    trajectory_id, created = store_trajectory(
        session=session,
        model=model,
        states=outcome.path,
        source=origin.store_source,
        robot_id=origin.store_robot_id,
        scene_hash=scene.hash,
        env=scene.env,
        planning_time_ms=clock.plan * 1e3,
        max_states=ctx.settings.max_trajectory_states,
        compute_quality=False,  # computed after the answer, with the plan record
    )
    clock.db += time.perf_counter() - t
    # The usage of the failed candidates, the event and the new trajectory's quality (its
    # clearance in the scene it was planned in) are written in order, off the request path.
    job = None
    if created:
        path = outcome.path
        job = QualityJob(trajectory_id, lambda: quality_columns(model, path, ctx.settings, scene))
    timings = clock.timings()
    event = _event_values(
        robot_id, model, scene, PlanStatus.SUCCESS, PlanSource.PLANNER, trajectory_id, tried,
        timings, seed=seed,
    )  # fmt: skip
    record = ctx.records.submit(PlanRecord(utcnow(), None, tuple(failed), event, quality=job))
    return PlanAnswer(
        PlanStatus.SUCCESS,
        PlanSource.PLANNER,
        trajectory_id,
        outcome.path,
        tried,
        timings,
        rejected=rejected,
        record=record,
    )
