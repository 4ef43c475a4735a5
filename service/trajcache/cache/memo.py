"""Validation memo: key states already certified in a scene are not checked a second time.

A trajectory's verdict depends only on its key states, the robot model (its id is the content
hash of the robot), the scene (its hash is the content hash of every object and value) and the
validator's settings — a :class:`MemoScope`. The memo remembers, per scope, digests of key-state
sequences that passed certified validation; it never remembers a failure, so the worst a memo
entry can do is skip work whose outcome is already known to be "valid".

Validation checks each straight segment between consecutive key states on its own (samples are
placed per segment, and each segment is certified by its two end samples), so a path is safe
when every one of its segments is. :func:`validate_with_memo` uses that:

- the whole adapted path was certified before in this scope → valid, nothing to check;
- its interior (every key state but the first and last) was certified before → only the first
  and last segments, the ones that endpoint substitution changed, are validated;
- otherwise the whole path is validated, and on success both it and its interior are remembered.

Digests are SHA-256 of the exact float64 bytes, so any change of any value — a different
endpoint, a base re-anchored by 1 µm, a reversed playback — is a different entry.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from trajcache.cache.index import Match
from trajcache.core.lru import LRU
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import (
    TrajectoryValidator,
    ValidationResult,
    ValidationSettings,
    ValidationStatus,
    settings_key_of,
)

__all__ = [
    "MemoScope",
    "MemoUse",
    "ValidationMemo",
    "is_proved",
    "proved_first",
    "remember_path",
    "validate_with_memo",
]

ValidateFn = Callable[[FloatArray], ValidationResult]
SegmentsFn = Callable[[FloatArray, list[int]], ValidationResult]


@dataclass(frozen=True)
class MemoScope:
    """Everything besides the key states that a validation verdict depends on."""

    model_id: str
    scene_hash: str
    settings: tuple[object, ...]  # the validator's `settings_key` (resolution, certified mode, …)

    @classmethod
    def under(
        cls, model: RobotModel, scene: Scene, settings: ValidationSettings
    ) -> MemoScope | None:
        """The scope of the verdicts of `build_validator(model, scene, settings)`, without
        building it (None: the scene has no content hash)."""
        if not scene.hash:
            return None
        return cls(model.model_id, scene.hash, settings_key_of(settings))

    @classmethod
    def of(cls, validator: TrajectoryValidator) -> MemoScope | None:
        """The scope of `validator`'s verdicts (None: its scene has no content hash)."""
        if not validator.scene_hash:
            return None
        return cls(validator.model.model_id, validator.scene_hash, validator.settings_key)


class MemoUse(str, Enum):
    """How much validation a memo lookup saved."""

    NONE = "none"  # the whole path was validated
    ENDS = "ends"  # only the first and last segments were validated
    WHOLE = "whole"  # the exact path was certified before
    CERTIFICATE = "certificate"  # the ends, and the interior against objects its certificate lacks


class ValidationMemo:
    """Thread-safe bounded LRU of (scope, key-state digest) pairs that passed validation."""

    def __init__(self, capacity: int = 8192) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be at least 1, not {capacity}")
        self.capacity = capacity
        self._entries: LRU[tuple[MemoScope, bytes], bool] = LRU(capacity=capacity)

    def known_valid(self, scope: MemoScope, states: FloatArray) -> bool:
        """Whether exactly these key states passed validation in `scope`."""
        return self._entries.get((scope, _digest(states))) is not None

    def remember(self, scope: MemoScope, states: FloatArray) -> None:
        """Record that these key states passed certified validation in `scope`."""
        self._entries.put((scope, _digest(states)), True)

    def clear(self) -> None:
        """Forget everything."""
        self._entries.clear()

    def __len__(self) -> int:
        return len(self._entries)


def _digest(states: FloatArray) -> bytes:
    array = np.ascontiguousarray(states, dtype=np.float64)
    digest = hashlib.sha256(f"{array.shape}".encode())
    digest.update(array.tobytes())
    return digest.digest()


def validate_with_memo(
    states: FloatArray,
    *,
    validate_fn: ValidateFn,
    memo: ValidationMemo,
    scope: MemoScope | None,
    segments_fn: SegmentsFn | None = None,
) -> tuple[ValidationResult, MemoUse]:
    """Validate an (n, D) path with `validate_fn`, skipping what `memo` already certified.

    `segments_fn` (the validator's `validate_segments`) checks the first and last segments in
    one pass; without it, each is validated on its own. `scope` None (e.g. a scene without a
    content hash) validates the whole path and remembers nothing.
    """
    if scope is None:
        return validate_fn(states), MemoUse.NONE
    if memo.known_valid(scope, states):
        return ValidationResult(ValidationStatus.VALID, 0, 0), MemoUse.WHOLE
    interior = states[1:-1]
    if len(states) >= 4 and memo.known_valid(scope, interior):
        if segments_fn is not None:
            result = segments_fn(states, [0, len(states) - 2])
        else:
            result = _validate_ends(states, validate_fn)
        if result.valid:
            memo.remember(scope, states)
        return result, MemoUse.ENDS
    result = validate_fn(states)
    if result.valid:
        remember_path(memo, scope, states)
    return result, MemoUse.NONE


def remember_path(memo: ValidationMemo, scope: MemoScope, states: FloatArray) -> None:
    """Remember a path that passed certified validation in `scope`, and its interior (what an
    adaptation of it to new ends keeps)."""
    memo.remember(scope, states)
    if len(states) >= 4:
        memo.remember(scope, states[1:-1])


def is_proved(
    memo: ValidationMemo, scope: MemoScope, states: FloatArray | None, reversed_: bool
) -> bool:
    """Whether the interior of a stored path (`states`; None: not read), as played (reversed
    with `reversed_`), passed certified validation in `scope`."""
    if states is None or len(states) < 3:
        return False
    return memo.known_valid(scope, states[1:-1][::-1] if reversed_ else states[1:-1])


def proved_first(
    memo: ValidationMemo,
    scope: MemoScope,
    matches: Sequence[Match],
    stored: Mapping[int, FloatArray],
) -> list[Match]:
    """`matches` with those whose interior, as played (reversed for a reversed match), passed
    certified validation in `scope` first, each group in its order: adapted to new ends, such a
    candidate needs only its first and last segments proved. It orders candidates only: each is
    validated as before. (Candidates of other scenes, near in joint space, would otherwise be
    tried first where many paths share an end.)"""

    marks = [is_proved(memo, scope, stored.get(m.trajectory_id), m.reversed) for m in matches]
    return [m for m, p in zip(matches, marks, strict=True) if p] + [
        m for m, p in zip(matches, marks, strict=True) if not p
    ]


def _validate_ends(states: FloatArray, validate_fn: ValidateFn) -> ValidationResult:
    """Validate the first and the last segment; the first failure is the verdict."""
    head = validate_fn(states[:2])
    if not head.valid:
        return head
    tail = validate_fn(states[-2:])
    if not tail.valid:
        tail.samples += head.samples
        tail.narrow_checks += head.narrow_checks
        tail.subdivisions += head.subdivisions
        return tail
    return ValidationResult(
        ValidationStatus.VALID,
        head.samples + tail.samples,
        head.narrow_checks + tail.narrow_checks,
        head.subdivisions + tail.subdivisions,
        elapsed_ms=head.elapsed_ms + tail.elapsed_ms,
    )
