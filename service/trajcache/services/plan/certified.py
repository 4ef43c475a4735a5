"""A cached candidate's validation: the memo first, then its stored certificate, else in full.

- The validation memo (`cache.memo`) knows exact paths and interiors this process certified in
  this very scene: nothing, or only the new first and last segments, is checked.
- Otherwise the candidate's certificate (`geometry/validation/certificates.py`), from this or
  another replica (`services.catalog.certificates`): the first and last segments are checked in
  full, the interior only against the scene's objects the certificate lacks, less those that
  moved by less than the clearance it keeps for them and those clear of its swept envelope.
- Either way, the first and last segments only where the clearance measured along the stored
  path's ends (`geometry/validation/end_clearance.py`, after it was planned) leaves them.
- Otherwise the whole path is validated.

Every valid verdict on a path of four states or more gives its interior a certificate, holding
the scene's object digests (and those it held before): `attempt.certificates` collects them,
and the plan record writes them after the answer (`services.plan.answers`); where the verdict
proved objects the certificate lacked, the writer first measures their clearances (and, once
per certificate, the interior's swept envelope).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

from trajcache.cache.index import Match
from trajcache.cache.memo import MemoUse, remember_path, validate_with_memo
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import SceneObject, make_scene
from trajcache.geometry.validation.certificates import (
    CertificateKey,
    Held,
    ObjectClearance,
    merged,
    object_digests,
    path_digest,
    stamp_of,
    validate_with_certificate,
)
from trajcache.geometry.validation.end_clearance import (
    SegmentClearance,
    measure_clearance,
    validate_ends,
)
from trajcache.geometry.validation.envelope import Envelope
from trajcache.geometry.validation.object_clearance import interior_bounds
from trajcache.geometry.validation.validator import (
    TrajectoryValidator,
    ValidationResult,
    settings_key_of,
    validator_for,
)
from trajcache.services.bookkeeping.record_batch import WriterJob
from trajcache.services.catalog.certificates import CertificateWrite, Certified, ClearanceJob
from trajcache.services.plan.attempt import PlanAttempt

__all__ = ["certify_planned", "measure_ends", "validate_candidate"]


def validate_candidate(
    attempt: PlanAttempt, match: Match, adapted: FloatArray
) -> tuple[ValidationResult, MemoUse]:
    """The verdict on an adapted candidate, and what spared work (module docstring)."""
    ctx, scope, validator = attempt.ctx, attempt.memo_scope, attempt.validator
    attempt.ends_proved.clear()  # this candidate's, if its ends are validated alone
    attempt.ends_missing.clear()
    # A hit the memo knows (the same scene) needs no certificate: its key is not even computed.
    known = scope is None or _memo_knows(attempt, adapted)
    key = None if known else _key(attempt, adapted)
    if key is not None and scope is not None:
        with ctx.sessions() as session:
            certified = ctx.certificates.get(session, match.trajectory_id, key)
        if certified.objects:
            result, use = validate_with_certificate(
                adapted,
                full=validator,
                ends_fn=_ends_fn(attempt, match),
                scene_only=lambda objects: _scene_only(attempt, objects),
                scene=attempt.scene,
                held=Held(
                    certified.objects,
                    certified.clearances,
                    envelope.clear_of if (envelope := certified.envelope) else None,
                ),
                audit=ctx.settings.certificate_audit,
            )
            attempt.certificate_use = use
            if result.valid:
                remember_path(ctx.memo, scope, adapted)
                _keep(attempt, match.trajectory_id, key, certified, adapted)
                _measure(attempt, list(attempt.ends_missing))
            return result, MemoUse.CERTIFICATE
    ends_fn = _ends_fn(attempt, match)
    result, memo_use = validate_with_memo(
        adapted, validate_fn=validator.validate, segments_fn=ends_fn, memo=ctx.memo, scope=scope
    )
    if result.valid and memo_use is MemoUse.NONE and key is not None:
        _keep(attempt, match.trajectory_id, key, Certified(), adapted)
    if result.valid and memo_use is MemoUse.NONE:  # its stored ends were not looked up
        _look_up_ends(attempt, match)
    if result.valid:
        _measure(attempt, list(attempt.ends_missing))
    return result, memo_use


def certify_planned(attempt: PlanAttempt, trajectory_id: int, states: FloatArray) -> None:
    """Give a planned path that was certified in this scene, and stored, its certificate."""
    key = _key(attempt, states)
    if key is not None:
        _keep(attempt, trajectory_id, key, Certified(), states)


def measure_ends(attempt: PlanAttempt, states: FloatArray) -> None:
    """Have the record writer measure the clearance along the first and last segments of a
    path certified in the attempt's scene, for its later hits
    (`geometry/validation/end_clearance.py`)."""
    if len(states) >= 4:
        _measure(attempt, [states[:2].copy(), states[-2:].copy()])


def _measure(attempt: PlanAttempt, segments: list[FloatArray]) -> None:
    """Have the record writer measure `segments` (each (2, D), certified in the attempt's
    scene) and keep their clearances."""
    scope, ctx, scene = attempt.memo_scope, attempt.ctx, attempt.scene
    if scope is None or attempt.model.base is not BaseType.FIXED:
        return
    clearances, validator = ctx.end_clearances, attempt.validator
    segments = [s for s in segments if clearances.claim(scope, s)]  # none measured twice
    if not segments:
        return

    def run() -> None:
        for segment in segments:
            clearances.put(scope, segment, measure_clearance(validator, segment), scene)

    def within_budget() -> None:  # the writer's share of a core, or not at all
        try:
            ctx.measuring.spend(run)
        finally:
            for segment in segments:
                clearances.release(scope, segment)

    job = WriterJob("measuring end clearances", within_budget)
    attempt.writer_jobs.append(job)


def _look_up_ends(attempt: PlanAttempt, match: Match) -> None:
    """Note the candidate's stored end segments that have no clearance in this scene."""
    stored, scope = attempt.candidates.get(match.trajectory_id), attempt.memo_scope
    if stored is None or scope is None or len(stored) < 4:
        return
    oriented = stored[::-1] if match.reversed else stored
    for segment in (oriented[:2], oriented[-2:]):
        if attempt.ctx.end_clearances.get(scope, segment, attempt.scene) is None:
            attempt.ends_missing.append(segment.copy())


def _ends_fn(
    attempt: PlanAttempt, match: Match
) -> Callable[[FloatArray, list[int]], ValidationResult]:
    """The end segments' validation of a path adapted from `match`: only where the clearance
    measured along the stored segments leaves them unproved, if it was."""
    ctx, scope, validator = attempt.ctx, attempt.memo_scope, attempt.validator
    stored = attempt.candidates.get(match.trajectory_id)
    if scope is None or stored is None or attempt.model.base is not BaseType.FIXED:
        return validator.validate_segments
    oriented = stored[::-1] if match.reversed else stored

    def known(segment: FloatArray) -> SegmentClearance | None:
        found = ctx.end_clearances.get(scope, segment, attempt.scene)
        if found is None:
            attempt.ends_missing.append(segment.copy())
        return found

    return functools.partial(
        validate_ends,
        validator,
        stored=oriented,
        known=known,
        audit=ctx.settings.certificate_audit,
        proved=attempt.ends_proved,
    )


def _key(attempt: PlanAttempt, states: FloatArray) -> CertificateKey | None:
    """The key of the path's interior; None where no certificate applies (off, a path of fewer
    than four states, or a scene without a content hash)."""
    if not attempt.ctx.settings.certificates or len(states) < 4 or not attempt.scene.hash:
        return None
    stamp = stamp_of(settings_key_of(attempt.ctx.settings))  # as `attempt.validator`'s
    return CertificateKey(attempt.checked.model_id, stamp, path_digest(states[1:-1]))


def _memo_knows(attempt: PlanAttempt, states: FloatArray) -> bool:
    memo, scope = attempt.ctx.memo, attempt.memo_scope
    assert scope is not None
    return memo.known_valid(scope, states) or memo.known_valid(scope, states[1:-1])


def _keep(
    attempt: PlanAttempt,
    trajectory_id: int,
    key: CertificateKey,
    known: Certified,
    states: FloatArray,
) -> None:
    """Note the certificate of a valid verdict in this scene, for the plan record to write;
    where it proves objects the certificate lacked, their clearances are measured too (by the
    writer), along the interior of `states`."""
    objects = merged(known.objects, object_digests(attempt.scene))
    clearances, envelope = None, known.envelope
    if objects != known.objects or not known.clearances or envelope is None:
        validator, interior = attempt.validator, states[1:-1].copy()
        # the objects measured already: the sweep alone, the clearances carried over
        same = objects == known.objects and bool(known.clearances)
        scene = make_scene([]) if same else attempt.scene
        budget = attempt.ctx.measuring
        found: list[tuple[dict[str, ObjectClearance], Envelope | None]] = []

        def work() -> None:  # the envelope is the path's and the variant's alone: once
            found.append(interior_bounds(validator, interior, scene, sweep=envelope is None))

        def measure() -> tuple[dict[str, ObjectClearance], Envelope | None]:
            budget.spend(work)  # within the writer's share, or none
            return found[0] if found else ({}, None)

        clearances = ClearanceJob(measure, kept=known.clearances, envelope=envelope)
    elif known.clearances:
        clearances = ClearanceJob(lambda: ({}, None), kept=known.clearances, envelope=envelope)
    write = CertificateWrite(trajectory_id, key, objects, clearances)
    attempt.ctx.certificates.put(write)
    attempt.certificates.append(write)


def _scene_only(attempt: PlanAttempt, objects: list[SceneObject]) -> TrajectoryValidator:
    """A validator of the checked model against `objects` alone, without self-collision, with
    the scene's allowed pairs that name them; shared, as every validator is."""
    ids = {obj.id.partition("#")[0] for obj in objects}
    allowed = [pair for pair in attempt.scene.allowed if pair[0] in ids or pair[1] in ids]
    part = make_scene(objects, allowed=allowed)
    ctx = attempt.ctx
    return validator_for(
        attempt.checked, part, ctx.settings, cache=ctx.validators, self_collision=False
    )
