"""Repair of a near-miss candidate, as OMPL's Lightning does: keep the good parts of the best
rejected candidate and plan only across the stretch that failed.

The best candidate that collided or came too close (the first in ranking order) is validated
again, forwards and backwards: `segment` of each finding (`TrajectoryValidator.validate`) is the
key segment where it lies, the first failing one forwards (key state `a` starts it) and the last
one backwards (key state `b` ends it). A finding exactly at a key state moves that end one state
outward. These only choose the stretch to replace: validation stops at a colliding sample
without looking at what lies between earlier ones, so the kept prefix and suffix are not
thereby proved.

When prefix and suffix keep at least half of the candidate's length (`KEEP`), the planner pool
plans from state `a` to state `b` with the repair budget (`repair_budget_s`), and the joined
path is validated whole, as any path the service answers with. It is stored as a new trajectory
naming its parent, and answered with source "repaired". Otherwise, or when the planner finds
nothing, or the joined path fails validation, the full planner runs as before.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.validation.validator import ValidationResult, ValidationStatus
from trajcache.jobs.pool import PlannerPool
from trajcache.services.plan.attempt import PlanAnswer, PlanAttempt, PlanSource
from trajcache.services.plan.fallback import problem_of, store_and_answer

__all__ = ["KEEP", "repair_candidate"]

KEEP = 0.5  # a repair keeps at least this share of the candidate's length
_MENDABLE = (ValidationStatus.COLLISION, ValidationStatus.TOO_CLOSE)


def repair_candidate(attempt: PlanAttempt, planner: PlannerPool) -> PlanAnswer | None:
    """The repaired answer, or None when no candidate can be repaired (module docstring)."""
    budget = min(attempt.ctx.settings.repair_budget_s, attempt.request.budget_s)
    best = next((r for r in attempt.rejections if r.result.status in _MENDABLE), None)
    if budget <= 0.0 or best is None or len(best.states) < 3:
        return None
    path = np.asarray(best.states, dtype=float)
    with attempt.clock.measure("validate"):
        stretch = _failing_stretch(attempt, path)
    if stretch is None:
        return None
    a, b = stretch
    problem = dataclasses.replace(
        problem_of(attempt),
        start=tuple(float(v) for v in path[a]),
        goal=tuple(float(v) for v in path[b]),
        budget_s=budget,
    )
    with attempt.clock.measure("plan"):
        attempt.session.rollback()  # nothing is written yet; release the connection
        outcome = planner.submit(problem)
    if not outcome.solved or outcome.path is None:
        return None
    middle = np.asarray(outcome.path, dtype=float)
    if len(middle) < 2 or not (
        np.allclose(middle[0], path[a]) and np.allclose(middle[-1], path[b])
    ):
        return None
    middle[0], middle[-1] = path[a], path[b]
    joined = np.vstack([path[:a], middle, path[b + 1 :]])
    with attempt.clock.measure("validate"):
        result = attempt.validator.validate(joined)  # whole: the kept parts are not proved
    if not result.valid:
        return None
    seed = outcome.seed if outcome.seed is not None else problem.seed
    return store_and_answer(
        attempt, joined, outcome, seed, source=PlanSource.REPAIRED, parent=best.trajectory_id
    )


def _failing_stretch(attempt: PlanAttempt, path: FloatArray) -> tuple[int, int] | None:
    """Key states (a, b), a < b: the stretch between them holds every finding of either pass;
    None when what lies outside it is less than `KEEP` of the path's length."""
    validator, n = attempt.validator, len(path)
    forward = validator.validate(path)
    if forward.valid or forward.segment < 0:
        return None
    backward = validator.validate(path[::-1])
    if backward.valid or backward.segment < 0:
        return None
    a = forward.segment - _at_key(forward, path, forward.segment)
    last = n - 2 - backward.segment  # the last failing segment, as the path runs
    b = last + 1 + _at_key(backward, path, last + 1)
    if a < 0 or b > n - 1 or b <= a:
        return None
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    if steps[:a].sum() + steps[b:].sum() < KEEP * steps.sum():
        return None
    return a, b


def _at_key(result: ValidationResult, path: FloatArray, k: int) -> int:
    """1 when the finding is at key state k itself (so that state is not free), else 0."""
    return int(result.state is not None and bool(np.array_equal(result.state, path[k])))
