"""Trajectory validation as in the paper, made certified.

The paper interpolates a trajectory with steps of at most 0.04 m (base position), 0.04 rad (base
orientation) and 0.035 rad (each joint) and checks every sample. A thin obstacle can still hide
between two samples. Certified mode closes that gap.

The bound. For two consecutive samples a and b, `link_motion_bounds` gives per link l a number
δ_l = Σ_d c[l, d]·|b_d − a_d| (θ difference wrapped) that no point of the link's geometry moves
more than along the straight segment from a to b. A point p(t) on that segment lies within
t·δ_l of p(0) and within (1 − t)·δ_l of p(1), so within δ_l/2 of one of them. Hence if at both
samples the link is farther than δ_l/2 from an obstacle, the swept volume is free. For a pair of
links the distance between them changes by at most δ_i + δ_j, so (δ_i + δ_j)/2 at both ends
certifies the pair.

Near-contact motions are not thrown away: a sample closer than its pad but not touching makes
the segments around it ambiguous, and those segments alone are split in half (δ halves with
them) until every piece is certified, a sample actually collides, or the pad falls below
`min_pad` (then the motion passes within a tenth of a millimetre and is rejected).
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from enum import Enum
from typing import Protocol

import numpy as np

from trajcache.geometry.collision import AMBIGUOUS, CollisionChecker, Contact
from trajcache.geometry.kinematics import check_states, link_motion_bounds
from trajcache.geometry.robot import BaseType, RobotModel
from trajcache.geometry.scene import Scene
from trajcache.geometry.shapes import FloatArray

_CHUNK = 256


class ValidationStatus(str, Enum):
    """Outcome of validating one trajectory."""

    VALID = "valid"
    COLLISION = "collision"
    OUT_OF_LIMITS = "out_of_limits"
    TOO_CLOSE = "too_close"


@dataclass(frozen=True)
class Resolution:
    """Largest interpolation step per kind of state value."""

    position_m: float = 0.04
    orientation_rad: float = 0.04
    joint_rad: float = 0.035


@dataclass
class ValidationResult:
    """What validation found, with counters for the statistics."""

    status: ValidationStatus
    samples: int
    narrow_checks: int
    subdivisions: int = 0
    state: FloatArray | None = None
    contacts: list[Contact] = field(default_factory=list)
    message: str = ""
    elapsed_ms: float = 0.0

    @property
    def valid(self) -> bool:
        """True when the whole trajectory is safe."""
        return self.status is ValidationStatus.VALID


def segment_deltas(states: FloatArray, *, planar: bool) -> FloatArray:
    """Differences between consecutive states, with the base angle taking the short way."""
    return _steps(states[:-1], states[1:], planar=planar)


def _steps(starts: FloatArray, ends: FloatArray, *, planar: bool) -> FloatArray:
    delta = ends - starts
    if planar:
        delta[:, 2] = (delta[:, 2] + np.pi) % (2.0 * np.pi) - np.pi
    return delta


def interpolate(key_states: FloatArray, model: RobotModel, resolution: Resolution) -> FloatArray:
    """Dense samples along the straight segments between key states, key states included."""
    key = np.asarray(key_states, dtype=float)
    if len(key) < 2:
        return key.copy()
    planar = model.base is BaseType.PLANAR
    delta = segment_deltas(key, planar=planar)
    off = model.arm_offset
    steps = np.zeros(len(delta))
    if planar:
        steps = np.maximum(steps, np.linalg.norm(delta[:, :2], axis=1) / resolution.position_m)
        steps = np.maximum(steps, np.abs(delta[:, 2]) / resolution.orientation_rad)
    if delta.shape[1] > off:
        steps = np.maximum(steps, np.max(np.abs(delta[:, off:]), axis=1) / resolution.joint_rad)
    counts = np.maximum(np.ceil(steps - 1e-9).astype(np.int64), 1)
    seg = np.repeat(np.arange(len(delta)), counts)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    frac = (np.arange(counts.sum()) - np.repeat(starts, counts)) / np.repeat(counts, counts)
    dense = key[seg] + frac[:, None] * delta[seg]
    return np.vstack([dense, key[-1:]])


class TrajectoryValidator:
    """Validates trajectories of one model in one scene; cheap to build, geometry is cached."""

    def __init__(
        self,
        model: RobotModel,
        scene: Scene,
        *,
        resolution: Resolution | None = None,
        certified: bool = True,
        min_pad: float = 1e-4,
        max_depth: int = 12,
    ) -> None:
        self.model = model
        self.checker = CollisionChecker(model, scene)
        self.resolution = resolution or Resolution()
        self.certified = certified
        self.min_pad = min_pad
        self.max_depth = max_depth
        rg = self.checker.robot
        bounds = link_motion_bounds(model)
        self._element_bounds = bounds[rg.element_link]  # (E, D)
        self._pair_bounds = self._element_bounds[rg.pair_i] + self._element_bounds[rg.pair_j]

    def validate(self, key_states: FloatArray) -> ValidationResult:
        """Check limits and collisions along the whole trajectory; stops at the first collision."""
        began = time.perf_counter()
        key = check_states(self.model, key_states, name="trajectory state")
        samples = interpolate(key, self.model, self.resolution)
        result = self._validate_samples(samples)
        result.elapsed_ms = (time.perf_counter() - began) * 1e3
        return result

    def _validate_samples(self, samples: FloatArray) -> ValidationResult:
        bad = self._limit_violation(samples)
        if bad is not None:
            return ValidationResult(
                ValidationStatus.OUT_OF_LIMITS,
                len(samples),
                0,
                state=samples[bad],
                message=self._limit_message(samples[bad]),
            )
        planar = self.model.base is BaseType.PLANAR
        abs_delta = np.abs(segment_deltas(samples, planar=planar))
        seg_elem = abs_delta @ self._element_bounds.T if self.certified else None  # (N-1, E)
        seg_pair = abs_delta @ self._pair_bounds.T if self.certified else None  # (N-1, P)
        checks = 0
        ambiguous_segments: list[int] = []
        for lo in range(0, len(samples), _CHUNK):
            hi = min(lo + _CHUNK, len(samples))
            epad = ppad = None
            if seg_elem is not None and seg_pair is not None:
                epad = _sample_pads(seg_elem, lo, hi) / 2.0
                ppad = _sample_pads(seg_pair, lo, hi) / 2.0
            verdict = self.checker.check(samples[lo:hi], element_pad=epad, pair_pad=ppad)
            checks += verdict.narrow_checks
            if verdict.first_collision >= 0:
                index = lo + verdict.first_collision
                return self._collision(samples, index, checks, verdict.contacts)
            for local in np.flatnonzero(verdict.status == AMBIGUOUS):
                index = lo + int(local)
                ambiguous_segments.extend(
                    s for s in (index - 1, index) if 0 <= s < len(samples) - 1
                )
        if not ambiguous_segments:
            return ValidationResult(ValidationStatus.VALID, len(samples), checks)
        return self._refine(samples, sorted(set(ambiguous_segments)), checks)

    def _refine(self, samples: FloatArray, segments: list[int], checks: int) -> ValidationResult:
        """Split ambiguous segments in half until certified, colliding, or too close to call."""
        planar = self.model.base is BaseType.PLANAR
        pending = np.stack([samples[segments], samples[np.asarray(segments) + 1]], axis=1)
        subdivisions = 0
        for _depth in range(self.max_depth):
            starts, ends = pending[:, 0], pending[:, 1]
            delta = _steps(starts, ends, planar=planar)
            mids = starts + delta / 2.0
            half = np.abs(delta) / 2.0
            epad = half @ self._element_bounds.T / 2.0  # pad of each half-segment
            ppad = half @ self._pair_bounds.T / 2.0
            seg_pad = np.maximum(epad.max(axis=1, initial=0.0), ppad.max(axis=1, initial=0.0))
            if np.any(seg_pad < self.min_pad):
                break
            points = np.concatenate([starts, mids, ends])
            verdict = self.checker.check(
                points, element_pad=np.tile(epad, (3, 1)), pair_pad=np.tile(ppad, (3, 1))
            )
            checks += verdict.narrow_checks
            subdivisions += len(pending)
            if verdict.first_collision >= 0:
                return self._collision(
                    points,
                    verdict.first_collision,
                    checks,
                    verdict.contacts,
                    samples=len(samples),
                    subdivisions=subdivisions,
                )
            k = len(pending)
            amb = verdict.status == AMBIGUOUS
            a_start, a_mid, a_end = amb[:k], amb[k : 2 * k], amb[2 * k :]
            left = a_start | a_mid
            right = a_mid | a_end
            pending = np.concatenate(
                [
                    np.stack([starts[left], mids[left]], axis=1),
                    np.stack([mids[right], ends[right]], axis=1),
                ]
            )
            if len(pending) == 0:
                return ValidationResult(ValidationStatus.VALID, len(samples), checks, subdivisions)
        state = pending[0, 0]
        return ValidationResult(
            ValidationStatus.TOO_CLOSE,
            len(samples),
            checks,
            subdivisions,
            state=state,
            contacts=self.checker.state_contacts(state),
            message="the motion passes closer to an obstacle than can be certified",
        )

    def _collision(
        self,
        states: FloatArray,
        index: int,
        checks: int,
        contacts: list[Contact],
        *,
        samples: int | None = None,
        subdivisions: int = 0,
    ) -> ValidationResult:
        state = states[index]
        text = "; ".join(c.describe() for c in contacts) or "collision"
        return ValidationResult(
            ValidationStatus.COLLISION,
            samples if samples is not None else len(states),
            checks,
            subdivisions,
            state=state,
            contacts=contacts,
            message=text,
        )

    def _limit_violation(self, samples: FloatArray) -> int | None:
        m = self.model
        off = m.arm_offset
        arm = samples[:, off:]
        bad = np.any((arm < m.lower[off:] - 1e-9) | (arm > m.upper[off:] + 1e-9), axis=1)
        hits = np.flatnonzero(bad)
        return int(hits[0]) if len(hits) else None

    def _limit_message(self, state: FloatArray) -> str:
        m = self.model
        names = m.state_names
        parts = [
            f"{names[i]}={state[i]:.4f} outside [{m.lower[i]:.4f}, {m.upper[i]:.4f}]"
            for i in range(m.arm_offset, m.dof)
            if not m.lower[i] - 1e-9 <= state[i] <= m.upper[i] + 1e-9
        ]
        return "; ".join(parts)


def _sample_pads(seg: FloatArray, lo: int, hi: int) -> FloatArray:
    """Per-sample pad: the larger bound of the two segments that meet at the sample."""
    zero = np.zeros((1, seg.shape[1]))
    padded = np.vstack([zero, seg, zero])  # row k + 1 holds segment k
    idx = np.arange(lo, hi)
    return np.maximum(padded[idx], padded[idx + 1])


class ValidationSettings(Protocol):
    """The part of the service settings that shapes validation."""

    step_position_m: float
    step_orientation_rad: float
    step_joint_rad: float
    certified_validation: bool


_validators: OrderedDict[tuple[object, ...], TrajectoryValidator] = OrderedDict()
_validators_lock = threading.Lock()
_VALIDATOR_CACHE = 128


def validator_for(
    model: RobotModel, scene: Scene, settings: ValidationSettings
) -> TrajectoryValidator:
    """A shared validator for this model, scene version and resolution (built once)."""
    resolution = Resolution(
        settings.step_position_m, settings.step_orientation_rad, settings.step_joint_rad
    )
    scene_key = scene.hash or f"id:{id(scene)}"
    key = (model.model_id, scene_key, resolution, settings.certified_validation)
    with _validators_lock:
        found = _validators.get(key)
        if found is not None:
            _validators.move_to_end(key)
            return found
    built = TrajectoryValidator(
        model, scene, resolution=resolution, certified=settings.certified_validation
    )
    with _validators_lock:
        _validators[key] = built
        while len(_validators) > _VALIDATOR_CACHE:
            _validators.popitem(last=False)
    return built
