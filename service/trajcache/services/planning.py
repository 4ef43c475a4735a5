"""The plan flow (paper, section 3): lookup → adapt → validate → fallback → store → answer."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.cache.adapt import adapt_trajectory, base_is_still
from trajcache.cache.index import Match
from trajcache.db.models import PlanEvent, Trajectory, unpack_states, utcnow
from trajcache.geometry.errors import CollisionStateError
from trajcache.geometry.kinematics import check_limits, check_states
from trajcache.geometry.robot import RobotModel
from trajcache.geometry.scene import Scene, scene_to_payload
from trajcache.geometry.validation import ValidationResult, validator_for
from trajcache.planning.problem import PlannerStatus, PlanningProblem, SceneSource
from trajcache.services.context import ServiceContext
from trajcache.services.models import get_model, model_source
from trajcache.services.robots import current_scene
from trajcache.services.trajectories import store_trajectory


class PlanStatus(str, Enum):
    """How a plan request ended."""

    SUCCESS = "success"
    MISS = "miss"  # no valid cached candidate and no fallback planning asked for or available
    FAILURE = "failure"  # the planner found no path within its budget
    ERROR = "error"  # the planner could not run (pool broken, backend down)


class PlanSource(str, Enum):
    """Where an answered trajectory came from."""

    CACHE = "cache"
    PLANNER = "planner"


@dataclass(frozen=True)
class PlanRequest:
    """A validated plan request with its options resolved against the settings."""

    start: np.ndarray
    goal: np.ndarray
    threshold: float
    max_candidates: int
    fallback: bool = True
    budget_s: float = 2.0
    planner: str = "rrtconnect"
    arm_only: bool = False  # match on arm joints only when the base does not move


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


@dataclass
class _Clock:
    began: float = field(default_factory=time.perf_counter)
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
    """Answer one plan request from the cache, or from the planner when nothing cached is safe."""
    clock = _Clock()
    with ctx.sessions() as session:
        t = time.perf_counter()
        robot, scene, _version = current_scene(
            session=session, scenes=ctx.scenes, robot_id=robot_id
        )
        model = get_model(session=session, registry=ctx.models, model_id=robot.model_id)
        start = check_states(model, request.start, name="start")[0]
        goal = check_states(model, request.goal, name="goal")[0]
        check_limits(model, start, name="start")
        check_limits(model, goal, name="goal")
        clock.db += time.perf_counter() - t

        t = time.perf_counter()
        index = ctx.indexes.index(session, model)
        arm_only = request.arm_only and base_is_still(start, goal, arm_offset=model.arm_offset)
        matches = index.query(
            start,
            goal,
            threshold=request.threshold,
            limit=request.max_candidates,
            arm_only=arm_only,
        )
        candidates = _load_states(session, [m.trajectory_id for m in matches])
        clock.lookup += time.perf_counter() - t

        t = time.perf_counter()
        validator = validator_for(model, scene, ctx.settings)
        failed: list[int] = []
        rejected: list[dict[str, object]] = []
        for match in matches:
            stored = candidates.get(match.trajectory_id)
            if stored is None:  # deleted since the index was read
                continue
            adapted = adapt_trajectory(
                stored, start, goal, arm_offset=model.arm_offset, reverse=match.reversed
            )
            result = validator.validate(adapted)
            if result.valid:
                clock.validate += time.perf_counter() - t
                return _answer_hit(
                    session, ctx, robot_id, model, scene, match, adapted, failed, rejected, clock
                )
            failed.append(match.trajectory_id)
            rejected.append(_rejection(match, result))
        clock.validate += time.perf_counter() - t

        _raise_if_endpoint_collides(validator, start, goal)
        if not request.fallback or ctx.planner is None:
            why = "fallback planning disabled" if not request.fallback else "no planner configured"
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


def _load_states(session: Session, ids: list[int]) -> dict[int, np.ndarray]:
    if not ids:
        return {}
    rows = session.execute(
        sa.select(Trajectory.id, Trajectory.states, Trajectory.n_states, Trajectory.dof).where(
            Trajectory.id.in_(ids)
        )
    ).all()
    return {r.id: unpack_states(r.states, n_states=r.n_states, dof=r.dof) for r in rows}


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
    if failed:
        session.execute(
            sa.update(Trajectory)
            .where(Trajectory.id.in_(failed))
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
) -> PlanEvent:
    return PlanEvent(
        robot_id=robot_id,
        model_id=model.model_id,
        scene_hash=scene.hash,
        status=status.value,
        source=source.value if source else None,
        trajectory_id=trajectory_id,
        candidates_tried=tried,
        lookup_ms=timings["lookup"],
        validate_ms=timings["validate"],
        plan_ms=timings["plan"],
        total_ms=timings["total"],
        error=(error or None) and error[:500],
    )


def _answer_hit(
    session: Session,
    ctx: ServiceContext,
    robot_id: str,
    model: RobotModel,
    scene: Scene,
    match: Match,
    states: np.ndarray,
    failed: list[int],
    rejected: list[dict[str, object]],
    clock: _Clock,
) -> PlanAnswer:
    t = time.perf_counter()
    tried = len(failed) + 1
    _record_usage(session, match.trajectory_id, failed)
    timings = clock.timings()
    session.add(
        _event(
            robot_id,
            model,
            scene,
            PlanStatus.SUCCESS,
            PlanSource.CACHE,
            match.trajectory_id,
            tried,
            timings,
        )
    )
    session.commit()
    clock.db += time.perf_counter() - t
    return PlanAnswer(
        PlanStatus.SUCCESS,
        PlanSource.CACHE,
        match.trajectory_id,
        states,
        tried,
        clock.timings(),
        rejected=rejected,
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
) -> PlanAnswer:
    t = time.perf_counter()
    _record_usage(session, None, failed)
    session.add(_event(robot_id, model, scene, status, None, None, tried, clock.timings(), message))
    session.commit()
    clock.db += time.perf_counter() - t
    return PlanAnswer(status, None, None, None, tried, clock.timings(), message, rejected)


def _plan_fallback(
    session: Session,
    ctx: ServiceContext,
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
    """Plan in the worker pool, validate like a cached trajectory, store and answer."""
    assert ctx.planner is not None
    t = time.perf_counter()
    problem = PlanningProblem(
        model=model_source(session=session, model_id=model.model_id, registry=ctx.models),
        scene=SceneSource(hash=scene.hash, payload=scene_to_payload(scene)),
        start=tuple(float(v) for v in start),
        goal=tuple(float(v) for v in goal),
        budget_s=request.budget_s,
        planner=request.planner,
    )
    outcome = ctx.planner.submit(problem)
    clock.plan += time.perf_counter() - t
    if not outcome.solved or outcome.path is None:
        status = PlanStatus.ERROR if outcome.status is PlannerStatus.ERROR else PlanStatus.FAILURE
        message = f"{outcome.status.value}: {outcome.message}".rstrip(": ")
        return _answer_without_path(
            session, robot_id, model, scene, status, tried, failed, rejected, clock, message
        )
    t = time.perf_counter()
    result = validator_for(model, scene, ctx.settings).validate(outcome.path)
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
        )
    t = time.perf_counter()
    _record_usage(session, None, failed)
    trajectory_id, _created = store_trajectory(
        session=session,
        model=model,
        states=outcome.path,
        source="planner",
        robot_id=robot_id,
        scene_hash=scene.hash,
        env=scene.env,
        planning_time_ms=clock.plan * 1e3,
        max_states=ctx.settings.max_trajectory_states,
        commit=False,
    )
    session.add(
        _event(
            robot_id,
            model,
            scene,
            PlanStatus.SUCCESS,
            PlanSource.PLANNER,
            trajectory_id,
            tried,
            clock.timings(),
        )
    )
    session.commit()
    clock.db += time.perf_counter() - t
    return PlanAnswer(
        PlanStatus.SUCCESS,
        PlanSource.PLANNER,
        trajectory_id,
        outcome.path,
        tried,
        clock.timings(),
        rejected=rejected,
    )
