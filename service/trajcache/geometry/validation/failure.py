"""Where a rejected trajectory failed: the first failing sample, and the pairs or joints at fault.

Validation stops at its first finding and keeps only what it needs for the verdict: the failing
state and the first contact FCL reported (`ValidationResult`). Everything a person asks next —
which of the validated samples that was, how far along the path, every pair in contact there —
is worked out here, after the fact and only for a rejection, so that validating a path that
passes costs nothing more.

The failing state lies on the path's dense samples (`validator.interpolate`): it is a sample
(a limit violation, a colliding sample) or a point on the straight step between two samples
where certification found contact or could not certify (`at` > 0). A path validated in parts
(the validation memo checks only the first and last segments of a path whose interior it
knows) is sampled the same way segment by segment, so the state is found on the whole path's
samples all the same.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trajcache.geometry.collision.checker import Contact
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import state_steps
from trajcache.geometry.validation.sampling import sample_counts
from trajcache.geometry.validation.validator import (
    TrajectoryValidator,
    ValidationResult,
    ValidationStatus,
    interpolate,
)

__all__ = ["Failure", "locate_failure"]

_ON_PATH = 1e-7  # how far (rad or m, in state space) the failing state may be from the path
_LIMIT_TOL = 1e-9


@dataclass(frozen=True)
class Failure:
    """The first failing point of a rejected path, on its validation samples."""

    status: ValidationStatus
    sample: int  # index of the validation sample at or just before the failing state
    at: float  # fraction of the step to the next sample (0: the sample itself)
    samples: int  # validation samples of the whole path
    segment: int  # the path's segment (between key states `segment` and `segment + 1`)
    state: FloatArray
    contacts: list[Contact] = field(default_factory=list)  # pairs in contact, or too close
    joints: list[str] = field(default_factory=list)  # joints out of limits

    @property
    def position(self) -> float:
        """How far along the samples the failure is (`sample` + `at`)."""
        return self.sample + self.at


def locate_failure(
    validator: TrajectoryValidator, key_states: FloatArray, result: ValidationResult
) -> Failure | None:
    """Where `result`, a rejection of `key_states` by `validator`, failed; None if it did not.

    A collision names every pair in contact at the failing state (FCL's verdict, as validation
    uses it); a motion too close to certify names the pairs certification left open.
    """
    if result.valid or result.state is None:
        return None
    model = validator.model
    key = np.asarray(key_states, dtype=float)
    samples = interpolate(key, model, validator.resolution)
    state = np.asarray(result.state, dtype=float)
    sample, at = _place(samples, state, base=model.base)
    counts = sample_counts(key, model, validator.resolution) if len(key) > 1 else np.ones(1)
    segment = int(np.searchsorted(np.cumsum(counts), sample, side="right"))
    contacts = list(result.contacts)
    if result.status is ValidationStatus.COLLISION:
        contacts = validator.checker.state_contacts(state) or contacts
    joints = []
    if result.status is ValidationStatus.OUT_OF_LIMITS:
        off = model.arm_offset
        outside = (state < model.lower - _LIMIT_TOL) | (state > model.upper + _LIMIT_TOL)
        joints = [model.state_names[i] for i in np.flatnonzero(outside) if i >= off]
    return Failure(
        status=result.status,
        sample=sample,
        at=at,
        samples=len(samples),
        segment=min(segment, max(len(key) - 2, 0)),
        state=state,
        contacts=contacts,
        joints=joints,
    )


def _place(samples: FloatArray, state: FloatArray, *, base: BaseType) -> tuple[int, float]:
    """(i, t): `state` is samples[i] + t · (samples[i + 1] − samples[i]), the first such step;
    the nearest step when none holds it within `_ON_PATH`."""
    if len(samples) < 2:
        return 0, 0.0
    starts = samples[:-1]
    steps = state_steps(starts, samples[1:], base=base)
    offsets = state_steps(starts, state[None, :], base=base)
    length2 = np.einsum("ij,ij->i", steps, steps)
    t = np.einsum("ij,ij->i", offsets, steps) / np.where(length2 > 0.0, length2, 1.0)
    t = np.clip(t, 0.0, 1.0)
    miss = np.linalg.norm(offsets - t[:, None] * steps, axis=1)
    close = np.flatnonzero(miss <= _ON_PATH)
    i = int(close[0]) if len(close) else int(np.argmin(miss))
    frac = float(t[i])
    if frac >= 1.0 - 1e-9:  # the next sample itself
        return i + 1, 0.0
    return i, 0.0 if frac <= 1e-9 else frac
