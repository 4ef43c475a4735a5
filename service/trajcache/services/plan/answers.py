"""The answers of a plan attempt: a hit, a planned path, or none, and the extras asked for.

Each answer is built here from its attempt, and what it leaves behind (its record, the ranking
facts, its count in the metrics) is described once, as a `PlanOutcome`, and handed to
`services.bookkeeping.outcomes.record_outcome`, whatever the outcome and whoever asked (a robot
or a seed job). Nothing here writes to the database.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from trajcache.cache.memo import MemoUse
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.scene import Scene
from trajcache.services.bookkeeping.answer_quality import AnswerExtras, answer_details
from trajcache.services.bookkeeping.outcomes import PlanOutcome, record_outcome
from trajcache.services.bookkeeping.record_batch import QualityJob
from trajcache.services.context import ServiceContext
from trajcache.services.errors import InvalidInputError
from trajcache.services.plan.attempt import PlanAnswer, PlanAttempt, PlanSource, PlanStatus
from trajcache.timing import TimingError

__all__ = [
    "PlannedPath",
    "answer_hit",
    "answer_planned",
    "answer_without_path",
    "describe_answer",
]


def answer_hit(
    attempt: PlanAttempt, trajectory_id: int, states: np.ndarray, memo: MemoUse
) -> PlanAnswer:
    """Answer with a validated cached trajectory; its bookkeeping is queued, not awaited."""
    attempt.tried = len(attempt.rejections) + 1
    timings = attempt.clock.timings()
    outcome = _Outcome(
        PlanStatus.SUCCESS, PlanSource.CACHE, trajectory_id=trajectory_id, served=trajectory_id
    )
    record = _record(attempt, outcome, timings)
    return PlanAnswer(
        PlanStatus.SUCCESS,
        PlanSource.CACHE,
        trajectory_id,
        states,
        attempt.tried,
        timings,
        rejected=attempt.rejections.listed(),
        record=record,
        memo=memo,
        certificate=attempt.certificate_use if memo is MemoUse.CERTIFICATE else None,
        ends_proved=_mean(attempt.ends_proved),
    )


@dataclass(frozen=True)
class PlannedPath:
    """A trajectory the planner found (or mended) and stored, as its answer reports it.

    `phases` are the planner's own times, added to the answer's timings (not to its record);
    `stored` is false when the path was identical to a trajectory already stored; `source` is
    REPAIRED for a cached path the planner mended (`services.plan.repair`).
    """

    trajectory_id: int
    states: np.ndarray
    seed: int | None
    planner: str | None = None
    phases: Mapping[str, float] | None = None
    stored: bool = True
    source: PlanSource = PlanSource.PLANNER


def answer_planned(
    attempt: PlanAttempt, planned: PlannedPath, *, quality: QualityJob | None
) -> PlanAnswer:
    """Answer with the trajectory the planner found (stored); its quality is written later."""
    timings = attempt.clock.timings()
    p = planned
    outcome = _Outcome(PlanStatus.SUCCESS, p.source, trajectory_id=p.trajectory_id, seed=p.seed)
    record = _record(attempt, outcome, timings, quality=quality)
    return PlanAnswer(
        PlanStatus.SUCCESS,
        p.source,
        p.trajectory_id,
        p.states,
        attempt.tried,
        {**timings, **(p.phases or {})},
        rejected=attempt.rejections.listed(),
        record=record,
        planner=p.planner,
        stored=p.stored,
    )


def answer_without_path(
    attempt: PlanAttempt, status: PlanStatus, message: str, *, seed: int | None = None
) -> PlanAnswer:
    """Answer a miss, a failure or an error: no trajectory, and why."""
    timings = attempt.clock.timings()
    record = _record(attempt, _Outcome(status, error=message, seed=seed), timings)
    return PlanAnswer(
        status,
        None,
        None,
        None,
        attempt.tried,
        timings,
        message,
        attempt.rejections.listed(),
        record=record,
    )


@dataclass(frozen=True)
class _Outcome:
    """How a request ended, in the plan's terms (its event and `PlanOutcome` are made of it);
    `served` is the cached trajectory a hit returned."""

    status: PlanStatus
    source: PlanSource | None = None
    trajectory_id: int | None = None
    error: str | None = None
    seed: int | None = None
    served: int | None = None


def _record(
    attempt: PlanAttempt,
    outcome: _Outcome,
    timings: Mapping[str, float],
    *,
    quality: QualityJob | None = None,
) -> int:
    """Hand the answer's outcome to the bookkeeping (`services.bookkeeping.outcomes`)."""
    event = attempt.event(
        outcome.status,
        source=outcome.source,
        trajectory_id=outcome.trajectory_id,
        timings=timings,
        error=outcome.error,
        seed=outcome.seed,
    )
    ctx, origin, rejections = attempt.ctx, attempt.origin, attempt.rejections
    details = None
    if rejections:  # where each failed: worked out by the writer, not here
        details = rejections.details(attempt.validator, attempt.start, attempt.goal, origin.held)
    return record_outcome(
        PlanOutcome(
            event,
            timings,
            served=outcome.served,
            real=origin.real,
            failed=rejections.ids(),
            details=details,
            quality=quality,
            certificates=tuple(attempt.certificates),
            jobs=tuple(attempt.writer_jobs),
        ),
        records=ctx.records,
        facts=ctx.facts,
    )


def describe_answer(
    *,
    ctx: ServiceContext,
    answer: PlanAnswer,
    model: RobotModel,
    scene: Scene,
    extras: AnswerExtras,
) -> PlanAnswer:
    """`answer` with the details `extras` ask for, their cost in its timings (ms).

    A timing the request's limits cannot satisfy is the caller's error (422).
    """
    if answer.states is None:
        return answer
    try:
        details = answer_details(
            settings=ctx.settings,
            validators=ctx.validators,
            model=model,
            scene=scene,
            states=answer.states,
            timing=extras.timing,
            level=extras.quality,
        )
    except TimingError as exc:
        raise InvalidInputError(f"options.timing: {exc}") from None
    answer.details = details
    answer.timings_ms.update({k: round(v, 3) for k, v in details.timings_ms.items()})
    return answer


def _mean(shares: list[float]) -> float | None:
    return round(sum(shares) / len(shares), 4) if shares else None
