"""The answers of a plan attempt, each with its bookkeeping queued on the ordered record writer.

Whatever the outcome — a hit, a miss, a planner failure, a planned trajectory — the usage
counters of the candidates and the plan event go to `ctx.records` (`services.plan.records`) as
one :class:`PlanRecord`, stamped with the writer's clock; nothing here writes to the database.
"""

from __future__ import annotations

import numpy as np

from trajcache.cache.memo import MemoUse
from trajcache.services.plan.attempt import PlanAnswer, PlanAttempt, PlanSource, PlanStatus
from trajcache.services.plan.records import PlanRecord, QualityJob

__all__ = ["answer_hit", "answer_planned", "answer_without_path"]


def answer_hit(
    attempt: PlanAttempt, trajectory_id: int, states: np.ndarray, memo: MemoUse
) -> PlanAnswer:
    """Answer with a validated cached trajectory; its bookkeeping is queued, not awaited."""
    attempt.tried = len(attempt.failed) + 1
    timings = attempt.clock.timings()
    event = attempt.event(
        PlanStatus.SUCCESS, source=PlanSource.CACHE, trajectory_id=trajectory_id, timings=timings
    )
    record = _submit(attempt, event, served=trajectory_id)
    return PlanAnswer(
        PlanStatus.SUCCESS,
        PlanSource.CACHE,
        trajectory_id,
        states,
        attempt.tried,
        timings,
        rejected=attempt.rejected,
        record=record,
        memo=memo,
    )


def answer_planned(
    attempt: PlanAttempt,
    trajectory_id: int,
    states: np.ndarray,
    *,
    seed: int | None,
    quality: QualityJob | None,
) -> PlanAnswer:
    """Answer with the trajectory the planner found (stored); its quality is written later."""
    timings = attempt.clock.timings()
    event = attempt.event(
        PlanStatus.SUCCESS,
        source=PlanSource.PLANNER,
        trajectory_id=trajectory_id,
        timings=timings,
        seed=seed,
    )
    record = _submit(attempt, event, quality=quality)
    return PlanAnswer(
        PlanStatus.SUCCESS,
        PlanSource.PLANNER,
        trajectory_id,
        states,
        attempt.tried,
        timings,
        rejected=attempt.rejected,
        record=record,
    )


def answer_without_path(
    attempt: PlanAttempt, status: PlanStatus, message: str, *, seed: int | None = None
) -> PlanAnswer:
    """Answer a miss, a failure or an error: no trajectory, and why."""
    timings = attempt.clock.timings()
    event = attempt.event(status, timings=timings, error=message, seed=seed)
    record = _submit(attempt, event)
    return PlanAnswer(
        status,
        None,
        None,
        None,
        attempt.tried,
        timings,
        message,
        attempt.rejected,
        record=record,
    )


def _submit(
    attempt: PlanAttempt,
    event: dict[str, object],
    *,
    served: int | None = None,
    quality: QualityJob | None = None,
) -> int:
    """Queue the attempt's record; a served candidate also updates the ranking facts now."""
    records = attempt.ctx.records
    at = records.now()
    real = attempt.origin.real and served is not None
    failed = tuple(attempt.failed)
    record = records.submit(PlanRecord(at, served, failed, event, real=real, quality=quality))
    if served is not None:
        attempt.ctx.facts.record(served=served, failed=attempt.failed, real=real, at=at)
    return record
