"""The cached candidates a plan request rejected, and why, as its answer and plan event say it.

The plan flow notes each rejected candidate as validated (`RejectedCandidate`: the path adapted
to the request and the validator's verdict) in the request's one list, :class:`Rejections`, and
nothing more: a request that ends in a hit after rejections answers as fast as without them.
Everything else is read from that list: the ids whose usage counters and ranking facts record a
failure, the reasons the answer lists, the verdict a later candidate that adapts to the same
path reuses, and the candidate a repair starts from. Where each failed is worked out by the
record writer, off the request path (`EventDetails`, `geometry.validation.failure`), into one
entry per candidate of the event's `rejections` column:

    {"trajectory_id", "reversed", "status", "reason",
     "start", "goal",                      the request's: adapt the stored path to them again
     "sample", "at", "samples", "segment", the first failing validation sample (`at`: the
                                           fraction of the step to the next one), of how many,
                                           on which segment between key states
     "state",                              the configuration that failed
     "pairs": [{"link", "other", "kind"}], links and objects (`scene`) or links (`self`)
     "joints",                             joints out of limits
     "held"}                               the robot's own held joint values ({}: the model's),
                                           so the view poses the links as they were validated
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.validation.failure import locate_failure
from trajcache.geometry.validation.validator import TrajectoryValidator, ValidationResult
from trajcache.services.bookkeeping.record_batch import EventDetails

__all__ = ["RejectedCandidate", "Rejections", "rejection_entries"]

MAX_REASON = 500


@dataclass(frozen=True)
class RejectedCandidate:
    """A cached candidate that failed validation, as it was validated."""

    trajectory_id: int
    reversed: bool
    states: FloatArray  # the candidate adapted to the request: the path that was validated
    result: ValidationResult


class Rejections:
    """The candidates one request rejected, in the order they were tried."""

    __slots__ = ("_items",)

    def __init__(self) -> None:
        self._items: list[RejectedCandidate] = []

    def add(self, candidate: RejectedCandidate) -> None:
        """Note a candidate that failed validation."""
        self._items.append(candidate)

    def __iter__(self) -> Iterator[RejectedCandidate]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def ids(self) -> tuple[int, ...]:
        """The rejected trajectories, in the order they were tried."""
        return tuple(r.trajectory_id for r in self._items)

    def verdict(self, states: FloatArray) -> ValidationResult | None:
        """The verdict of a rejected candidate adapted to exactly `states`, if one was."""
        return next((r.result for r in self._items if np.array_equal(r.states, states)), None)

    def listed(self) -> list[dict[str, object]]:
        """Why each failed, as the answer lists it."""
        return [
            {"trajectory_id": r.trajectory_id, "status": r.result.status.value,
             "reason": r.result.message}
            for r in self._items
        ]  # fmt: skip

    def details(
        self,
        validator: TrajectoryValidator,
        start: FloatArray,
        goal: FloatArray,
        held: Mapping[str, float] | None,
    ) -> EventDetails:
        """The event's `rejections` column, worked out by the record writer when it writes."""
        rejected = tuple(self._items)
        return EventDetails(
            lambda: {"rejections": rejection_entries(validator, start, goal, rejected, held)}
        )


def rejection_entries(
    validator: TrajectoryValidator,
    start: FloatArray,
    goal: FloatArray,
    rejected: Sequence[RejectedCandidate],
    held: Mapping[str, float] | None = None,
) -> list[dict[str, Any]]:
    """The `rejections` column of a plan event: where and on what each candidate failed."""
    entries = []
    for candidate in rejected:
        result = candidate.result
        entry: dict[str, Any] = {
            "trajectory_id": candidate.trajectory_id,
            "reversed": candidate.reversed,
            "status": result.status.value,
            "reason": result.message[:MAX_REASON],
            "start": _values(start),
            "goal": _values(goal),
        }
        entry["held"] = {str(k): float(v) for k, v in (held or {}).items()}
        failure = locate_failure(validator, candidate.states, result)
        if failure is not None:
            entry.update(
                sample=failure.sample,
                at=round(failure.at, 6),
                samples=failure.samples,
                segment=failure.segment,
                state=_values(failure.state),
                pairs=[
                    {"link": c.link, "other": c.other, "kind": c.kind.value}
                    for c in failure.contacts
                ],
                joints=failure.joints,
            )
        entries.append(entry)
    return entries


def _values(state: FloatArray) -> list[float]:
    return [float(v) for v in np.asarray(state, dtype=float)]
