"""Planning until a path is certified: search, shortcut, certify, repair, and search again.

Certified validation rejects a path that the planner's sample checks passed when a segment
passes, between two samples, closer to something than the distance bounds can prove free. On
the example-robot-data arms that ended 13 of 40 problems of bench/real_robots.py (ur5, tiago),
and each time the unshortened path failed too: the rejected segments were the search's own,
not the shortcut's. So, within the budget:

1. Each search's path is shortcut and certified (`shortcut.shortcut_and_certify`).
2. When the first one is rejected, or no search finds any, an endpoint that no motion can
   leave certified (a pair's distance bound there is not positive) is INVALID_START /
   INVALID_GOAL: no search can help. (Asked only then: a certified path proves its ends, and
   the question costs two validations, a few per cent of a plan.)
3. A rejected path is repaired (`repair.repair_path`): each segment that fails certification
   is replaced by an RRIS detour whose segments are certified, within `REPAIR_S`.
4. Failing that, the next search: the random generators go on, so it finds another path.

The answer is SOLVED with a certified path, TIMEOUT when no search found any path, and
UNCERTIFIED when paths were found and none could be certified before the budget ran out.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from trajcache.geometry.collision.checker import ContactKind
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.validation.validator import TrajectoryValidator
from trajcache.planning.deadline import Deadline
from trajcache.planning.problem import PlannerStatus, PlanResult
from trajcache.planning.query import Query
from trajcache.planning.repair import SegmentFn, remembered, repair_path
from trajcache.planning.shortcut import shortcut_and_certify

# The search of attempt n (from 0) within the deadline: a raw path (N, D) or None.
SearchFn = Callable[[int, Deadline], Sequence[FloatArray] | FloatArray | None]
# A search from query.start to query.goal whose segments pass the given check (a detour).
DetourFn = Callable[[Query, Deadline, SegmentFn], list[FloatArray] | None]
REPAIR_S = 1.0  # one path's repair; past that a new search is the better bet
_SUMMED = ("shortcut_ms", "validate_ms")  # per-attempt timings that add up


def plan_until_certified(finisher: Finisher, *, search_fn: SearchFn, none_found: str) -> PlanResult:
    """Search, finish and repair paths until one is certified or the budget is spent.

    `finisher` holds the query, its validator and what finishing a path takes; `none_found`
    is the TIMEOUT message. Every attempt's counts and times go into `finisher.stats`.
    """
    query, validator, deadline, stats = (
        finisher.query,
        finisher.validator,
        finisher.deadline,
        finisher.stats,
    )
    found, reason = 0, ""
    for key in ("attempts", "paths_found", "repairs", "repair_ms", *_SUMMED):
        stats.setdefault(key, 0.0)
    for attempt in itertools.count():
        if attempt and deadline.expired():
            break
        stats["attempts"] += 1
        began = time.perf_counter()
        raw = search_fn(attempt, deadline)
        stats["plan_ms"] += (time.perf_counter() - began) * 1e3
        if raw is None:
            break
        found += 1
        stats["paths_found"] += 1
        path, reason = finisher.finish(raw)
        if path is not None:  # certified: whole, or segment by segment (the same verdict)
            return PlanResult(
                PlannerStatus.SOLVED, path, stats=stats, certificate=validator.certificate(path)
            )
        if finisher.stuck is not None:
            return PlanResult(finisher.stuck[0], message=finisher.stuck[1], stats=stats)
    if not found:  # a rejected path asked already (the finisher), so only now if none was
        stuck = _stuck_endpoint(query, validator)
        if stuck is not None:
            return PlanResult(stuck[0], message=stuck[1], stats=stats)
        return PlanResult(PlannerStatus.TIMEOUT, message=none_found, stats=stats)
    message = (
        f"no certifiable path within the budget ({found} found, none certified or repaired); "
        f"last: {reason}"
    )
    return PlanResult(PlannerStatus.UNCERTIFIED, message=message, stats=stats)


@dataclass
class Finisher:
    """Turns a found path into a certified one: shortcut and certify it, else repair it.

    `segment_fn` checks the shortcuts' segments; `certify` remembers its verdicts across
    attempts; counts and times go into `stats`. `repair_s` bounds one path's repair (a
    planner whose searches are fast does better to search again).
    """

    query: Query
    validator: TrajectoryValidator
    segment_fn: SegmentFn
    detour_fn: DetourFn
    deadline: Deadline
    rng: np.random.Generator
    shortcut_s: float
    stats: dict[str, float]
    repair_s: float | None = None  # None: `REPAIR_S`, read when a repair starts
    certify: SegmentFn = field(init=False)
    # after a rejected path: the status and message of an endpoint no motion can leave certified
    stuck: tuple[PlannerStatus, str] | None = field(init=False, default=None)
    _ends_asked: bool = field(init=False, default=False)

    def __post_init__(self) -> None:
        validator = self.validator
        self.certify = remembered(lambda a, b: validator.validate(np.stack([a, b])).valid)

    def finish(self, raw: Sequence[FloatArray] | FloatArray) -> tuple[FloatArray | None, str]:
        """The certified path (or None) and why the shortcut path was rejected (or "")."""
        finished = shortcut_and_certify(
            list(raw),
            segment_free_fn=self.segment_fn,
            distance_fn=self.query.spec.distance,
            interpolate_fn=self.query.spec.interpolate,
            validate_fn=lambda p: _verdict(self.validator, p),
            budget_s=self.shortcut_s,
            rng=self.rng,
        )
        for key in _SUMMED:
            self.stats[key] += finished.stats.pop(key, 0.0)
        self.stats.update(finished.stats)
        if finished.path is not None:
            return finished.path, ""
        if not self._ends_asked:  # no repair or search helps an endpoint no motion can leave
            self._ends_asked = True
            self.stuck = _stuck_endpoint(self.query, self.validator)
            if self.stuck is not None:
                return None, self.stuck[1]
        return self.repair(finished.short), finished.message

    def repair(self, path: Sequence[FloatArray]) -> FloatArray | None:
        """`path` with certified detours for its failing segments, within `repair_s`; or None."""
        began = time.perf_counter()
        budget = self.deadline.sub(REPAIR_S if self.repair_s is None else self.repair_s)
        repair = repair_path(
            path,
            certify_fn=self.certify,
            detour_fn=partial(_detour, self.detour_fn, self.query, budget, self.certify),
            budget=budget,
        )
        self.stats["repair_ms"] += (time.perf_counter() - began) * 1e3
        self.stats["repairs"] += repair.repaired
        if repair.path is None:
            return None
        self.stats["length_after"] = self.query.spec.path_length(repair.path)
        self.stats["waypoints_after"] = float(len(repair.path))
        return np.asarray(repair.path)


def _detour(
    detour_fn: DetourFn,
    query: Query,
    budget: Deadline,
    certify: SegmentFn,
    a: FloatArray,
    b: FloatArray,
) -> list[FloatArray] | None:
    """A detour a → b whose segments `certify` passes, by `detour_fn` within `budget`."""
    return detour_fn(replace(query, start=a, goal=b), budget, certify)


def _verdict(validator: TrajectoryValidator, path: FloatArray) -> tuple[bool, str]:
    result = validator.validate(path)
    return result.valid, result.message or result.status.value


def _stuck_endpoint(
    query: Query, validator: TrajectoryValidator
) -> tuple[PlannerStatus, str] | None:
    """The status and message for an endpoint that no motion can leave certified, or None.

    A motion of length zero certifies exactly when every pair's distance bound at the state is
    positive. Where one is not, the piece of any motion next to the state certifies only if the
    bound jumps just beside it: on the benchmark's arms none of 30 random motions from such a
    state did, and 60 searches in a row found no certifiable path.
    """
    if not validator.certified:
        return None
    for name, state, status in (
        ("start", query.start, PlannerStatus.INVALID_START),
        ("goal", query.goal, PlannerStatus.INVALID_GOAL),
    ):
        result = validator.validate(np.stack([state, state]))
        if not result.valid:
            near = "; ".join(
                f"link '{c.link}' near {'object' if c.kind is ContactKind.SCENE else 'link'} "
                f"'{c.other}'"
                for c in result.contacts
            )
            way = "from" if status is PlannerStatus.INVALID_START else "to"
            return status, (
                f"no motion {way} the {name} can be certified: its distance bound is not "
                f"positive ({near or result.message})"
            )
    return None


__all__ = ["REPAIR_S", "DetourFn", "SearchFn", "plan_until_certified"]
