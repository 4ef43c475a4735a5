"""Fallback to the planner: plan in the worker pool, validate like a cached trajectory, store.

The session's transaction ends before planning, so a request waiting on a worker holds no
database connection; storing the result opens a new one. Each request plans with a fresh seed (a
retry searches anew), recorded in its plan event. The new trajectory's quality (its clearance in
the scene it was planned in) is computed by the record writer, off the request path.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np

from trajcache.cache.memo import MemoScope, remember_path
from trajcache.cache.ranking import CandidateFacts
from trajcache.geometry.errors import CollisionStateError
from trajcache.geometry.validation.validator import certificate_for
from trajcache.jobs.pool import PlannerPool
from trajcache.planning.problem import (
    PlannerStatus,
    PlanningProblem,
    PlanResult,
    SceneSource,
    fresh_seed,
)
from trajcache.services.bookkeeping.records import QualityJob
from trajcache.services.catalog.models import model_source
from trajcache.services.catalog.trajectories import (
    NewTrajectory,
    quality_columns,
    set_parent,
    store_trajectory,
)
from trajcache.services.errors import UnavailableError
from trajcache.services.plan.answers import PlannedPath, answer_planned, answer_without_path
from trajcache.services.plan.attempt import PlanAnswer, PlanAttempt, PlanSource, PlanStatus
from trajcache.services.plan.certified import certify_planned, measure_ends

logger = logging.getLogger(__name__)

__all__ = ["check_endpoints", "plan_fallback", "store_and_answer"]

RECORD_WAIT_S = 10.0  # how long an unavailable planner's answer waits for its record


def plan_fallback(attempt: PlanAttempt, planner: PlannerPool) -> PlanAnswer:
    """Plan, validate, store and answer; an unavailable planner is a 503 (UnavailableError)."""
    with attempt.clock.measure("plan"):
        problem = problem_of(attempt)
        attempt.session.rollback()  # nothing is written yet; release the connection
        # the scene's validator, for the hits that follow, built while the worker plans
        outcome = planner.submit(problem, meanwhile=lambda: attempt.validator)
    # A coalesced or remembered answer ran with its leader's seed; an unrun one with none.
    seed = outcome.seed if outcome.seed is not None else problem.seed
    if not outcome.solved or outcome.path is None:
        return _unsolved(attempt, outcome, seed)
    with attempt.clock.measure("validate"):
        failure = _validation_failure(attempt, outcome)
    if failure:
        message = f"planned path failed validation: {failure}"
        return answer_without_path(attempt, PlanStatus.FAILURE, message, seed=seed)
    return store_and_answer(attempt, np.asarray(outcome.path, dtype=float), outcome, seed)


def store_and_answer(
    attempt: PlanAttempt,
    path: np.ndarray,
    outcome: PlanResult,
    seed: int | None,
    *,
    source: PlanSource = PlanSource.PLANNER,
    parent: int | None = None,
) -> PlanAnswer:
    """Store a path certified in the attempt's scene (a repaired one names its `parent`), give
    it its certificate, and answer with it; its quality is computed with the plan record."""
    model, scene, settings = attempt.model, attempt.scene, attempt.ctx.settings
    commit_ids: list[int] = []
    with attempt.clock.measure("db"):
        trajectory_id, created = store_trajectory(
            session=attempt.session,
            settings=settings,
            compute_quality=False,  # computed after the answer, with the plan record
            commit=parent is None,
            commit_ids=commit_ids,
            trajectory=NewTrajectory(
                model=model,
                states=path,
                source=attempt.origin.store_source,
                robot_id=attempt.origin.store_robot_id,
                scene_hash=scene.hash,
                env=scene.env,
                planning_time_ms=attempt.clock.seconds("plan") * 1e3,
                max_states=settings.max_trajectory_states,
            ),
        )
        if parent is not None:
            set_parent(attempt.session, trajectory_id, parent)
            attempt.session.commit()
    attempt.ctx.indexes.add_stored(  # committed: indexed now, not at the next sync
        model.model_id, trajectory_id, commit_ids[0] if commit_ids else None, path
    )
    if created:  # its ranking facts are known: a later lookup need not read them
        env = {str(k): float(v) for k, v in scene.env.items()}
        attempt.ctx.facts.put_many({trajectory_id: CandidateFacts(env=env)})
    certify_planned(attempt, trajectory_id, path)
    job = _quality_job(attempt, trajectory_id, path) if created else None
    measure_ends(attempt, path)  # by the writer, before its quality: a hit may follow at once
    planned = PlannedPath(
        trajectory_id,
        path,
        seed,
        planner=attempt.request.planner,
        phases=planner_phases(outcome.stats, attempt.clock.seconds("plan") * 1e3),
        stored=created,
        source=source,
    )
    return answer_planned(attempt, planned, quality=job)


def _quality_job(attempt: PlanAttempt, trajectory_id: int, path: np.ndarray) -> QualityJob:
    """The stored path's quality columns, computed by the record writer."""
    model, scene, settings = attempt.model, attempt.scene, attempt.ctx.settings
    validators = attempt.ctx.validators
    return QualityJob(
        trajectory_id, lambda: quality_columns(model, path, settings, scene, validators=validators)
    )


def planner_phases(stats: Mapping[str, float], plan_ms: float) -> dict[str, float]:
    """Where a planned answer's planning time went, from the worker's counters: the setup of
    the scene for it (parsed, the model's variant, the planner's sphere tables and endpoints;
    cached per scene), the search, the simplification (compiled, then shortcutting), the
    worker's certification and repair, the worker's whole run, and the pool's round trip."""
    search = stats.get("search_ms", stats.get("plan_ms", 0.0))
    simplify = stats.get("simplify_ms", 0.0) + stats.get("shortcut_ms", 0.0)
    run = stats.get("run_ms", 0.0)
    setup = sum(stats.get(k, 0.0) for k in ("setup_ms", "endpoints_ms", "tables_ms"))
    return {
        "setup": round(setup, 3),
        "search": round(search, 3),
        "simplify": round(simplify, 3),
        "certify": round(stats.get("validate_ms", 0.0), 3),
        "repair": round(stats.get("repair_ms", 0.0), 3),
        "worker": round(run, 3),
        "pool": round(max(plan_ms - run, 0.0), 3),
    }


def _validation_failure(attempt: PlanAttempt, outcome: PlanResult) -> str:
    """Why the planned path is not valid here ("" when it is). The worker's certificate
    stands for this service's own validation when its validator names the same verdict
    (`geometry/validation/stamp.py`: same certifier, model variant, scene, settings and
    states); otherwise the path is validated as a cached one would be."""
    assert outcome.path is not None
    model, scene, settings = attempt.checked, attempt.scene, attempt.ctx.settings
    here = certificate_for(model, scene, settings, outcome.path)
    if outcome.certificate and outcome.certificate == here:
        scope = MemoScope.under(model, scene, settings)
        if scope is not None:  # as if validated here: a replay's interior is known
            remember_path(attempt.ctx.memo, scope, np.asarray(outcome.path, dtype=float))
        return ""
    result = attempt.validator.validate(outcome.path)
    return "" if result.valid else result.message


def problem_of(attempt: PlanAttempt) -> PlanningProblem:
    """The planning problem of the attempt, certified by the worker as the flow validates."""
    ctx, scene, settings = attempt.ctx, attempt.scene, attempt.ctx.settings
    return PlanningProblem(
        model=model_source(
            session=attempt.session, model_id=attempt.model.model_id, registry=ctx.models
        ),
        scene=SceneSource.of(scene, stored=attempt.origin.scene_stored),
        start=tuple(float(v) for v in attempt.start),
        goal=tuple(float(v) for v in attempt.goal),
        budget_s=attempt.request.budget_s,
        planner=attempt.request.planner,
        seed=fresh_seed(),
        joint_values=tuple(sorted((attempt.origin.held or {}).items())),
        step_position_m=settings.step_position_m,
        step_orientation_rad=settings.step_orientation_rad,
        step_joint_rad=settings.step_joint_rad,
        certified_validation=settings.certified_validation,
    )


def check_endpoints(attempt: PlanAttempt) -> None:
    """A start or goal in collision is the caller's error (422), not a planning failure."""
    with attempt.clock.measure("validate"):
        checker = attempt.validator.checker
        for name, state in (("start", attempt.start), ("goal", attempt.goal)):
            contacts = checker.state_contacts(state)
            if contacts:
                text = "; ".join(c.describe() for c in contacts)
                raise CollisionStateError(
                    f"{name} state is in collision: {text}", contacts=contacts
                )


def _unsolved(attempt: PlanAttempt, outcome: PlanResult, seed: int | None) -> PlanAnswer:
    """A failure answer; an endpoint the planner refused is a 422 where it is in collision
    (`check_endpoints`); a planner that could not run raises a 503 the caller may retry, once
    its plan event is written."""
    if outcome.status in (PlannerStatus.INVALID_START, PlannerStatus.INVALID_GOAL):
        check_endpoints(attempt)
    status = PlanStatus.ERROR if outcome.status is PlannerStatus.ERROR else PlanStatus.FAILURE
    message = f"{outcome.status.value}: {outcome.message}".rstrip(": ")
    if outcome.detail:  # the plan event and the log have it; the robot's answer does not
        message = f"{message} ({outcome.detail})"
        logger.warning("planning could not run: %s", message)
    answer = answer_without_path(attempt, status, message, seed=seed)
    if status is PlanStatus.ERROR:
        if answer.record is not None:
            attempt.ctx.records.wait(answer.record, timeout=RECORD_WAIT_S)
        raise UnavailableError(f"planning is unavailable, retry later ({outcome.message})")
    return answer
