"""Why cached candidates were rejected, as the plan event records it.

The plan flow notes each rejected candidate as validated (`RejectedCandidate`: the path adapted
to the request and the validator's verdict) and nothing more: a request that ends in a hit
after rejections answers as fast as without them. Where each failed is worked out by the
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

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.validation.failure import locate_failure
from trajcache.geometry.validation.validator import TrajectoryValidator, ValidationResult

__all__ = ["RejectedCandidate", "rejection_entries"]

MAX_REASON = 500


@dataclass(frozen=True)
class RejectedCandidate:
    """A cached candidate that failed validation, as it was validated."""

    trajectory_id: int
    reversed: bool
    states: FloatArray  # the candidate adapted to the request: the path that was validated
    result: ValidationResult


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
