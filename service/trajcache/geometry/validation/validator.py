"""Trajectory validation as in the paper, made certified.

The paper interpolates a trajectory with steps of at most 0.04 m (base position), 0.04 rad (base
orientation) and 0.035 rad (each joint) and checks every sample. A thin obstacle can still hide
between two samples. Certified mode closes that gap.

The bound. Along the straight segment between two consecutive samples, every point of the robot
moves at most a computed distance (`model/motion.py`: for each dof, the change times the point's
largest distance from that dof's axis over the segment, from the configurations at both ends).
For an element and a scene object (or two robot elements, counting only the dofs that move one
of them and not the other) with distance lower bounds d_a, d_b at the two samples and motion
bound M, the distance anywhere on the segment is at least (d_a + d_b − M)/2, so d_a + d_b > M
certifies the segment for that pair (`certify.py`). The lower bounds are sound at every level
(`collision/clearance.py`: element balls, sphere covers, support-function slabs; FCL only supplies a
direction and the final collision test, never a distance).

Near-contact motions are not thrown away for being near: a pair no bound certifies is resolved
by conservative advancement, splitting only the part of its segment that neither end certifies,
until every piece is certified, a state actually collides, or a piece's motion bound falls below
`min_pad` (then the motion passes within about that distance of something and is TOO_CLOSE).
With `certified=False` only the samples are checked, with FCL's verdicts.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from enum import Enum
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from trajcache.core.lru import LRU
from trajcache.geometry.collision.checker import CollisionChecker, Contact, ContactKind
from trajcache.geometry.collision.shared import GeometryCache
from trajcache.geometry.model.kinematics import check_states
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import compiled_input, state_steps
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.certify import (
    MAX_DEPTH,
    MIN_PAD,
    CertifierOptions,
    SegmentCertifier,
)
from trajcache.geometry.validation.sampling import (
    Resolution,
    first_out_of_limits,
    interpolate,
    sample_counts,
)
from trajcache.geometry.validation.segments import Finding, SegmentStatus
from trajcache.geometry.validation.stamp import certificate_digest

IntArray = NDArray[np.int64]

_CHUNK = 256
CERTIFY_SUBDIVISION = 1  # certified samples per resolution step (`sampling.sample_counts`)
_SPREAD = 9  # samples checked first, spread along the trajectory, when it has
_SPREAD_ABOVE = 32  # more resolution steps than this (below, certifying them all costs no more)


class ValidationStatus(str, Enum):
    """Outcome of validating one trajectory."""

    VALID = "valid"
    COLLISION = "collision"
    OUT_OF_LIMITS = "out_of_limits"
    TOO_CLOSE = "too_close"


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
    sample: int = -1  # the sample (of `samples`) at or after which the finding lies
    segment: int = -1  # `validate`: the key segment (key state i to i + 1) where it lies

    @property
    def valid(self) -> bool:
        """True when the whole trajectory is safe."""
        return self.status is ValidationStatus.VALID

    def then(self, result: ValidationResult) -> ValidationResult:
        """The verdict of this check followed by `result`'s: the counters summed, in `result`
        if it failed (it is the verdict), else in this one."""
        kept = self if result.valid else result
        kept.samples = self.samples + result.samples
        kept.narrow_checks = self.narrow_checks + result.narrow_checks
        kept.subdivisions = self.subdivisions + result.subdivisions
        return kept


def settings_key(
    resolution: Resolution, certified: bool, min_pad: float = MIN_PAD, max_depth: int = MAX_DEPTH
) -> tuple[object, ...]:
    """Every setting a verdict depends on besides the model, the scene and the states."""
    return (resolution, certified, min_pad, max_depth)


class TrajectoryValidator:
    """Validates trajectories of one model in one scene; cheap to build, geometry is cached."""

    def __init__(
        self,
        model: RobotModel,
        scene: Scene,
        *,
        resolution: Resolution | None = None,
        certified: bool = True,
        certifier: CertifierOptions = CertifierOptions(),
        geometry: GeometryCache | None = None,
        self_collision: bool = True,
    ) -> None:
        self.model = model
        self.scene_hash = scene.hash  # "" for a scene without a content hash
        self.checker = CollisionChecker(
            model, scene, geometry=geometry, self_collision=self_collision
        )
        self.resolution = resolution or Resolution()
        self.certified = certified
        self.subdivision = CERTIFY_SUBDIVISION if certified else 1
        self.settings_key = settings_key(
            self.resolution, certified, certifier.min_pad, certifier.max_depth
        )
        if not self_collision:  # a verdict on the scene alone
            self.settings_key = (*self.settings_key, "scene only")
        self.certifier = SegmentCertifier(self.checker, base=model.base, options=certifier)

    def validate(self, key_states: FloatArray) -> ValidationResult:
        """Check limits and collisions along the whole trajectory; stops at the first collision."""
        began = time.perf_counter()
        key = check_states(self.model, key_states, name="trajectory state")
        samples = interpolate(key, self.model, self.resolution, self.subdivision)
        result = self._validate_samples(samples)
        if result.sample >= 0 and len(key) >= 2:
            ends = np.cumsum(sample_counts(key, self.model, self.resolution, self.subdivision))
            result.segment = min(int(np.searchsorted(ends, result.sample, side="right")),
                                 len(key) - 2)  # fmt: skip
        result.elapsed_ms = (time.perf_counter() - began) * 1e3
        return result

    def validate_segments(self, key_states: FloatArray, segments: list[int]) -> ValidationResult:
        """Check only the straight motions from key state i to i + 1, for i in `segments`, each
        as `validate` checks it; the first finding, in the order of `segments`, is the verdict
        (its counters cover every piece checked)."""
        began = time.perf_counter()
        key = check_states(self.model, key_states, name="trajectory state")
        total = ValidationResult(ValidationStatus.VALID, 0, 0)
        for i in segments:
            result = self._validate_samples(
                interpolate(key[i : i + 2], self.model, self.resolution, self.subdivision)
            )
            total = total.then(result)
            if not total.valid:
                break
        total.elapsed_ms = (time.perf_counter() - began) * 1e3
        return total

    def certificate(self, key_states: FloatArray) -> str:
        """The digest that names this validator's valid verdict on exactly these key states
        (`geometry/validation/stamp.py`): issued only for states it certified, compared by a
        process that would otherwise validate them again."""
        return certificate_digest(
            self.model.model_id, self.scene_hash, self.settings_key, key_states
        )

    def _validate_samples(self, samples: FloatArray) -> ValidationResult:
        bad = self._limit_violation(samples)
        if bad is not None:
            state = samples[bad]
            return _result(
                ValidationStatus.OUT_OF_LIMITS,
                samples,
                state=state,
                message=self._limit_message(state),
                sample=bad,
            )
        before = self.checker.narrow_checks
        if not self.certified or len(samples) < 2:
            for lo in range(0, len(samples), _CHUNK):
                verdict = self.checker.check(samples[lo : lo + _CHUNK])
                if verdict.first_collision >= 0:
                    state = samples[lo + verdict.first_collision]
                    checks = self.checker.narrow_checks - before
                    return _result(
                        ValidationStatus.COLLISION,
                        samples,
                        checks,
                        state=state,
                        contacts=verdict.contacts,
                        sample=lo + verdict.first_collision,
                    )
            return _result(ValidationStatus.VALID, samples, self.checker.narrow_checks - before)
        probes = 0
        upto = samples
        if len(samples) > _SPREAD_ABOVE * self.subdivision:
            # A few spread samples first: when one collides, only the samples up to it need
            # certifying (the earliest colliding sample is the finding either way).
            spread = np.unique(np.linspace(0, len(samples) - 1, _SPREAD).round().astype(np.int64))
            verdict = self.checker.check(samples[spread], stop_at_first=True)
            hit = verdict.first_collision
            if hit == 0:  # the first sample
                checks = self.checker.narrow_checks - before
                return _result(ValidationStatus.COLLISION, samples, checks, state=samples[0],
                               contacts=verdict.contacts, sample=0)  # fmt: skip
            upto = samples[: spread[hit] + 1] if hit > 0 else samples
        for lo in range(0, len(upto) - 1, _CHUNK):
            chunk = upto[lo : lo + _CHUNK + 1]  # consecutive chunks share their end sample
            found = self.certifier.certify(chunk)
            probes += found.subdivisions
            if found.status is not SegmentStatus.FREE:
                checks = self.checker.narrow_checks - before
                return self._finding(samples, chunk, lo, found, checks, probes)
        return _result(ValidationStatus.VALID, samples, self.checker.narrow_checks - before, probes)

    def _finding(
        self,
        samples: FloatArray,
        chunk: FloatArray,
        lo: int,
        found: Finding,
        checks: int,
        probes: int,
    ) -> ValidationResult:
        """The result for what certification stopped at, `lo` samples into the trajectory."""
        state = chunk[found.segment]
        if found.at > 0.0:
            delta = state_steps(state, chunk[found.segment + 1], base=self.model.base)
            state = state + found.at * delta
        if found.status is SegmentStatus.COLLISION:
            return _result(
                ValidationStatus.COLLISION,
                samples,
                checks,
                probes,
                state=state,
                contacts=found.contacts,
                sample=lo + found.segment,
            )
        near = "; ".join(
            f"link '{c.link}' near {'object' if c.kind is ContactKind.SCENE else 'link'} "
            f"'{c.other}'"
            for c in found.contacts
        )
        return _result(
            ValidationStatus.TOO_CLOSE,
            samples,
            checks,
            probes,
            state=state,
            contacts=found.contacts,
            message=f"the motion passes closer than can be certified ({near}) "
            f"between samples {lo + found.segment} and {lo + found.segment + 1}",
            sample=lo + found.segment,
        )

    def _limit_violation(self, samples: FloatArray) -> int | None:
        m = self.model
        found = first_out_of_limits(compiled_input(samples), m.lower, m.upper, m.arm_offset)
        return None if found < 0 else int(found)

    def _limit_message(self, state: FloatArray) -> str:
        m = self.model
        names = m.state_names
        parts = [
            f"{names[i]}={state[i]:.4f} outside [{m.lower[i]:.4f}, {m.upper[i]:.4f}]"
            for i in range(m.arm_offset, m.dof)
            if not m.lower[i] - 1e-9 <= state[i] <= m.upper[i] + 1e-9
        ]
        return "; ".join(parts)


def _result(
    status: ValidationStatus,
    samples: FloatArray,
    checks: int = 0,
    subdivisions: int = 0,
    *,
    state: FloatArray | None = None,
    contacts: list[Contact] | None = None,
    message: str | None = None,
    sample: int = -1,
) -> ValidationResult:
    """Every ValidationResult is built here; a collision's message names its contacts."""
    contacts = contacts or []
    if message is None and status is ValidationStatus.COLLISION:
        message = "; ".join(c.describe() for c in contacts) or "collision"
    return ValidationResult(
        status,
        len(samples),
        checks,
        subdivisions,
        state=state,
        contacts=contacts,
        message=message or "",
        sample=sample,
    )


class ValidationSettings(Protocol):
    """The part of the service settings that shapes validation."""

    step_position_m: float
    step_orientation_rad: float
    step_joint_rad: float
    certified_validation: bool


VALIDATOR_CACHE_SIZE = 128


class ValidatorCache:
    """Shared validators by model, scene version and settings, all on one GeometryCache."""

    def __init__(
        self, *, capacity: int = VALIDATOR_CACHE_SIZE, geometry: GeometryCache | None = None
    ) -> None:
        self.geometry = geometry or GeometryCache()
        self.validators: LRU[tuple[object, ...], TrajectoryValidator] = LRU(capacity=capacity)

    def clear(self) -> None:
        """Forget every validator and geometry."""
        self.validators.clear()
        self.geometry.clear()


def validator_for(
    model: RobotModel,
    scene: Scene,
    settings: ValidationSettings,
    *,
    cache: ValidatorCache,
    self_collision: bool = True,
) -> TrajectoryValidator:
    """A shared validator for this model, scene version and resolution (built once); without
    `self_collision`, of the scene alone."""
    scene_key = scene.hash or f"id:{id(scene)}"
    key: tuple[object, ...] = (model.model_id, scene_key, _resolution(settings))
    key = (*key, settings.certified_validation)
    if not self_collision:
        key = (*key, "scene only")
    return cache.validators.get_or_build(
        key,
        lambda: build_validator(
            model, scene, settings, geometry=cache.geometry, self_collision=self_collision
        ),
    )


def build_validator(
    model: RobotModel,
    scene: Scene,
    settings: ValidationSettings,
    *,
    geometry: GeometryCache | None = None,
    self_collision: bool = True,
) -> TrajectoryValidator:
    """A new validator with these settings (geometry from `geometry`, else this process's)."""
    return TrajectoryValidator(
        model,
        scene,
        resolution=_resolution(settings),
        certified=settings.certified_validation,
        geometry=geometry,
        self_collision=self_collision,
    )


def certificate_for(
    model: RobotModel, scene: Scene, settings: ValidationSettings, key_states: FloatArray
) -> str:
    """The certificate `build_validator(model, scene, settings)` would issue for these states,
    without building it (its collision geometry is not needed to name a verdict)."""
    return certificate_digest(model.model_id, scene.hash, settings_key_of(settings), key_states)


def settings_key_of(settings: ValidationSettings) -> tuple[object, ...]:
    """The `settings_key` of the validators `build_validator` makes under these settings."""
    return settings_key(_resolution(settings), settings.certified_validation)


def _resolution(settings: ValidationSettings) -> Resolution:
    return Resolution(
        settings.step_position_m, settings.step_orientation_rad, settings.step_joint_rad
    )
