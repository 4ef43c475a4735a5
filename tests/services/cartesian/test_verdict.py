"""The validator's word on a Cartesian joint path: the prefix kept is itself valid, also when a
finding lies exactly at a key state (the motion it begins is reported, the state left out)."""

from __future__ import annotations

from typing import Any, cast

import numpy as np

from trajcache.geometry.validation.validator import (
    TrajectoryValidator,
    ValidationResult,
    ValidationStatus,
)
from trajcache.planning.cartesian import CartesianStatus
from trajcache.services.cartesian.path import verdict_of


class KeyStateCollides:
    """A validator whose only collision is key state `bad` itself (segment numbering as the
    real one's: a finding at the last key state belongs to the last segment)."""

    def __init__(self, bad: int) -> None:
        self.bad, self.calls = bad, 0

    def validate(self, key_states: Any) -> ValidationResult:
        self.calls += 1
        n = len(key_states)
        if n <= self.bad:
            return ValidationResult(ValidationStatus.VALID, n, 0)
        result = ValidationResult(ValidationStatus.COLLISION, n, 0, message="'crate'")
        result.sample, result.segment = self.bad, max(-1, min(self.bad, n - 2))
        return result


def _verdict(bad: int, n: int = 6) -> tuple[int, str, CartesianStatus]:
    fake = cast(TrajectoryValidator, KeyStateCollides(bad))
    verdict = verdict_of(fake, np.zeros((n, 2)))
    return verdict.kept, verdict.message, verdict.status


def test_a_collision_at_a_key_state_leaves_that_state_out() -> None:
    kept, message, status = _verdict(2)
    assert kept == 2 and status is CartesianStatus.COLLISION
    assert "'crate'" in message and "from state 1 to 2" in message


def test_a_valid_path_is_kept_whole_and_a_colliding_start_alone() -> None:
    assert _verdict(9)[0] == 6
    kept, message, _ = _verdict(0)
    assert kept == 1 and "at the start" in message
