"""Stored certificates on a real service context (SQLite): what a valid verdict proved is kept
with the trajectory, another replica builds on it, and a shortened verdict is never wrong.

The robot is the two-joint arm; its cached path swings the shoulder from 0 to 1 rad. Every
context audits: each verdict a certificate shortened is proved again in full, and a
disagreement fails the request (`certificate_audit`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sqlalchemy as sa

from tests.services.hit_setup import context, store, two_joint
from trajcache.cache.memo import MemoUse
from trajcache.db.models import Trajectory, TrajectoryCertificate
from trajcache.geometry.errors import CollisionStateError
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.validation.certificates import (
    CertificateDisagreement,
    CertificateKey,
    ObjectClearance,
    object_digest,
)
from trajcache.geometry.validation.envelope import Envelope
from trajcache.geometry.validation.validator import Resolution, TrajectoryValidator, interpolate
from trajcache.services.catalog.certificates import (
    CertificateStore,
    CertificateWrite,
    Certified,
    ClearanceJob,
    decode,
    encode,
    footprint,
)
from trajcache.services.catalog.robots import put_robot
from trajcache.services.catalog.scene_writes import put_scene
from trajcache.services.context import ServiceContext
from trajcache.services.maintenance.transfer import ExportFilter, dumps, export_records
from trajcache.services.plan.flow import PlanAnswer, PlanRequest, PlanSource, plan

ARM_PATH = [[0.0, 0.0], [0.3, 0.2], [0.7, 0.2], [1.0, 0.0]]


def box(name: str, shoulder: float, *, reach: float = 0.25, size: float = 0.04) -> dict[str, Any]:
    """A box at `reach` m from the shoulder at angle `shoulder` (rad) in the arm's plane."""
    position = [reach * math.sin(shoulder), 0.0, 0.1 + reach * math.cos(shoulder)]
    return {"id": name, "type": "box", "size": [size] * 3, "pose": {"position": position}}


AWAY = [box("left", -1.2), box("right", 2.2), box("high", 0.5, reach=1.5)]
THIN = box("high", 0.5, size=0.01)  # in the sweep of the interior's segment only


@pytest.fixture
def url(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'certificates.db'}"


@pytest.fixture
def ctx(url: str) -> Iterator[ServiceContext]:
    with context(url, certificate_audit=True) as service:
        yield service


def robot(ctx: ServiceContext, objects: list[dict[str, Any]]) -> int:
    """Robot r1 in a scene of `objects`, with the arm's path stored; its id."""
    model = two_joint(ctx)
    with ctx.sessions() as session:
        put_robot(session=session, robot_id="r1", model_id=model.model_id)
    scene(ctx, objects)
    return store(ctx, model, ARM_PATH)


def scene(ctx: ServiceContext, objects: list[dict[str, Any]]) -> None:
    with ctx.sessions() as session:
        parsed = parse_scene({"objects": objects})
        put_scene(session=session, scenes=ctx.scenes, robot_id="r1", scene=parsed)


def ask(ctx: ServiceContext, start: float = 0.02, goal: float = 0.98) -> PlanAnswer:
    request = PlanRequest(
        start=np.array([start, 0.0]),
        goal=np.array([goal, 0.0]),
        threshold=0.2,
        max_candidates=3,
        fallback=False,
    )
    return plan(ctx=ctx, robot_id="r1", request=request)


def certificates(ctx: ServiceContext) -> list[TrajectoryCertificate]:
    assert ctx.records.flush(timeout=10)
    with ctx.sessions() as session:
        rows = list(session.scalars(sa.select(TrajectoryCertificate)))
        session.expunge_all()
    return rows


def test_a_valid_verdict_leaves_a_certificate_of_the_scenes_objects(ctx: ServiceContext) -> None:
    robot(ctx, AWAY)
    answer = ask(ctx)
    assert answer.source is PlanSource.CACHE and answer.memo is MemoUse.NONE
    (row,) = certificates(ctx)
    objects = parse_scene({"objects": AWAY}).objects
    assert sorted(row.objects) == sorted(object_digest(o) for o in objects)
    assert row.variant == answer_model(ctx)


def answer_model(ctx: ServiceContext) -> str:
    with ctx.sessions() as session:
        return str(session.scalars(sa.select(Trajectory.model_id)).one())


def test_a_moved_object_is_proved_again_alone(ctx: ServiceContext) -> None:
    robot(ctx, AWAY)
    assert ask(ctx).source is PlanSource.CACHE
    moved = [*AWAY[:2], box("high", 0.5, reach=1.51)]
    scene(ctx, moved)
    answer = ask(ctx, 0.03, 0.97)
    assert answer.source is PlanSource.CACHE and answer.memo is MemoUse.CERTIFICATE
    assert answer.certificate is not None
    assert (answer.certificate.objects, answer.certificate.reproved) == (3, 1)
    (row,) = certificates(ctx)  # the certificate now holds the moved object too
    assert len(row.objects) == 4


def test_an_object_moved_into_the_interior_is_found(ctx: ServiceContext) -> None:
    """The interior (0.3 → 0.7 rad) passes shoulder 0.5: an object put there is a collision,
    though the certificate holds every other object."""
    robot(ctx, AWAY)
    ask(ctx)
    scene(ctx, [*AWAY[:2], THIN])
    answer = ask(ctx, 0.03, 0.97)
    assert answer.source is None and answer.memo is None
    assert answer.rejected and "high" in str(answer.rejected[0]["reason"])


@pytest.mark.parametrize("seed", range(4))
def test_certified_verdicts_agree_with_a_dense_check(ctx: ServiceContext, seed: int) -> None:
    """Random scenes after the first: each answer that a certificate shortened is audited in
    full by the service, and checked here against 20× denser samples."""
    rng = np.random.default_rng(seed)
    robot(ctx, AWAY)
    ask(ctx)
    validator = TrajectoryValidator(two_joint(ctx), parse_scene({"objects": AWAY}))
    used = 0
    for k in range(12):
        placed = rng.uniform([-1.5, 0.15], [2.5, 0.45], size=(2, 2))
        objects = [box(f"o{i}", s, reach=r) for i, (s, r) in enumerate(placed)]
        scene(ctx, [*AWAY, *objects])
        start, goal = rng.uniform(-0.05, 0.05) + 0.02, rng.uniform(-0.05, 0.05) + 0.98
        try:
            answer = ask(ctx, start, goal)
        except CollisionStateError:  # an object on the start or the goal
            continue
        used += answer.memo is MemoUse.CERTIFICATE
        if answer.states is not None:
            fine = interpolate(answer.states, validator.model, Resolution(joint_rad=0.035 / 20))
            dense = TrajectoryValidator(
                validator.model, parse_scene({"objects": [*AWAY, *objects]}), certified=False
            )
            assert dense.checker.check(fine).first_collision < 0, (seed, k)
    assert used > 0


def test_another_replica_builds_on_the_stored_certificate(ctx: ServiceContext, url: str) -> None:
    robot(ctx, AWAY)
    ask(ctx)
    assert certificates(ctx)
    with context(url, certificate_audit=True) as other:
        moved = [*AWAY[:2], box("high", 0.5, reach=1.52)]
        scene(other, moved)
        answer = ask(other, 0.04, 0.96)
        assert answer.memo is MemoUse.CERTIFICATE and answer.certificate is not None
        # moved 2 cm, far less than the clearance its certificate keeps: nothing proved again
        assert (answer.certificate.reproved, answer.certificate.moved) == (0, 1)
        scene(other, [*AWAY[:2], box("high", 0.5, reach=2.0)])  # 0.5 m: more than it keeps
        answer = ask(other, 0.05, 0.95)
        assert answer.memo is MemoUse.CERTIFICATE and answer.certificate is not None
        use = answer.certificate  # yet still clear of the interior's swept envelope
        assert (use.reproved, use.moved, use.clear) == (0, 0, 1)
        scene(other, [*AWAY[:2], box("high", 0.5, reach=0.55, size=0.01)])  # inside it, free
        answer = ask(other, 0.06, 0.94)
        assert answer.memo is MemoUse.CERTIFICATE and answer.certificate is not None
        use = answer.certificate
        assert (use.reproved, use.moved, use.clear) == (1, 0, 0)


def test_a_certificate_keeps_each_object_s_clearance(ctx: ServiceContext) -> None:
    robot(ctx, AWAY)
    ask(ctx)
    (row,) = certificates(ctx)
    assert row.clearances is not None and set(row.clearances) == {"left", "right", "high"}
    for shape, pose, clearance in row.clearances.values():
        assert len(shape) == 32 and len(pose) == 12 and 0.0 < clearance <= 0.1
    objects = {o.id: o for o in parse_scene({"objects": AWAY}).objects}
    _, pose, _ = row.clearances["high"]
    assert np.array_equal(np.reshape(pose, (3, 4)), objects["high"].pose[:3])


def test_objects_moved_near_the_path_are_never_passed_unproved(url: str) -> None:
    """A box beside the interior's sweep, moved again and again by up to 4 cm: each move is
    either within the clearance kept (not proved again) or proved again; the audit proves every
    shortened verdict in full and fails on a disagreement."""
    rng = np.random.default_rng(3)
    seen = {"moved": 0, "reproved": 0, "rejected": 0}
    with context(url, certificate_audit=True) as ctx:
        near = {**box("near", 0.5, reach=0.25), "size": [0.03, 0.03, 0.03]}
        near["pose"] = {"position": [0.12, 0.07, 0.32]}
        robot(ctx, [near])
        ask(ctx)
        for k in range(40):
            moved = [near["pose"]["position"][i] + rng.uniform(-0.04, 0.04) for i in range(3)]
            scene(ctx, [{**near, "pose": {"position": moved}}])
            answer = ask(ctx, 0.02 + 0.001 * k, 0.98)
            certificates(ctx)  # the writer has written (and measured) what this one proved
            if answer.certificate is None:
                seen["rejected"] += 1
                continue
            seen["moved"] += answer.certificate.moved
            seen["reproved"] += answer.certificate.reproved
    assert seen["moved"] > 3 and seen["reproved"] > 3, seen


def test_other_settings_do_not_use_a_certificate(ctx: ServiceContext, url: str) -> None:
    robot(ctx, AWAY)
    ask(ctx)
    with context(url, step_joint_rad=0.02) as finer:
        scene(finer, [*AWAY[:2], box("high", 0.5, reach=1.52)])
        assert ask(finer, 0.04, 0.96).memo is MemoUse.NONE
        rows = certificates(finer)
    assert len({row.stamp for row in rows}) == 1  # the old stamp's certificate went


def test_certificates_go_with_their_trajectory(ctx: ServiceContext) -> None:
    trajectory_id = robot(ctx, AWAY)
    ask(ctx)
    assert certificates(ctx)
    with ctx.sessions() as session:
        session.execute(sa.delete(Trajectory).where(Trajectory.id == trajectory_id))
        session.commit()
    assert certificates(ctx) == []


def test_certificates_can_be_turned_off(url: str) -> None:
    with context(url, certificates=False) as ctx:
        robot(ctx, AWAY)
        ask(ctx)
        scene(ctx, [*AWAY[:2], box("high", 0.5, reach=1.52)])
        assert ask(ctx, 0.04, 0.96).memo is MemoUse.NONE
        assert certificates(ctx) == []


def test_the_audit_catches_a_certificate_that_claims_too_much(ctx: ServiceContext) -> None:
    """A forged certificate (here, put straight into the process's store) that names the object
    blocking the interior would pass the path unaudited; the audit proves it again and fails."""
    trajectory_id = robot(ctx, AWAY)
    ask(ctx)
    (row,) = certificates(ctx)
    blocked = [*AWAY[:2], THIN]
    (high,) = [o for o in parse_scene({"objects": blocked}).objects if o.id == "high"]
    forged = frozenset(row.objects) | {object_digest(high)}
    key = CertificateKey(row.variant, row.stamp, row.path)
    ctx.certificates.put(CertificateWrite(trajectory_id, key, forged))
    scene(ctx, blocked)
    with pytest.raises(CertificateDisagreement, match="high"):
        ask(ctx, 0.03, 0.97)


def test_an_export_carries_no_certificate(ctx: ServiceContext) -> None:
    """Certificates are the validator's own: an export (and so an import) never holds one."""
    robot(ctx, AWAY)
    ask(ctx)
    (row,) = certificates(ctx)
    with ctx.sessions() as session:
        text = "".join(dumps(r) for r in export_records(session=session, filt=ExportFilter()))
    assert row.path not in text and row.stamp not in text
    assert not any(digest in text for digest in row.objects)


def test_an_object_clear_of_the_swept_envelope_needs_no_proof(database_url: str) -> None:
    """A new object away from the interior's sweep is certified by the envelope the certificate
    keeps (read back from the table by another replica, SQLite and PostgreSQL); one inside it is
    proved again."""
    with context(database_url, certificate_audit=True) as ctx:
        robot(ctx, AWAY)
        ask(ctx)
        (row,) = certificates(ctx)
    assert row.envelope is not None and len(row.envelope) % 32 == 0  # (x, y, z, r) float64
    with context(database_url, certificate_audit=True) as other:
        scene(other, [*AWAY, box("new", -1.6, reach=0.3)])
        answer = ask(other, 0.04, 0.96)
        assert answer.memo is MemoUse.CERTIFICATE and answer.certificate is not None
        assert (answer.certificate.reproved, answer.certificate.clear) == (0, 1)
        scene(other, [*AWAY, box("beside", 0.5, reach=0.25, size=0.01)])  # THIN: in the sweep
        answer = ask(other, 0.05, 0.95)
        assert answer.source is None and answer.rejected


def test_the_audit_catches_an_envelope_that_claims_too_much(ctx: ServiceContext) -> None:
    """A forged envelope (a speck far away) would pass the object blocking the interior as
    clear of it; the audit proves the verdict again and fails."""
    trajectory_id = robot(ctx, AWAY)
    ask(ctx)
    (row,) = certificates(ctx)
    speck = Envelope(np.array([[5.0, 5.0, 5.0]]), np.array([0.001]))
    job = ClearanceJob(lambda: ({}, None), envelope=speck)
    key = CertificateKey(row.variant, row.stamp, row.path)
    ctx.certificates.put(CertificateWrite(trajectory_id, key, frozenset(row.objects), job))
    scene(ctx, [*AWAY, THIN | {"id": "thin"}])
    with pytest.raises(CertificateDisagreement, match="thin"):
        ask(ctx, 0.03, 0.97)


def test_a_missing_envelope_is_swept_alone(url: str) -> None:
    """A certificate that holds its objects' clearances but no envelope (an older row, or a
    writer out of its share) gains the envelope at the next valid verdict; the clearances are
    carried over as they were, not measured again."""
    with context(url, certificate_audit=True) as ctx:
        robot(ctx, AWAY)
        ask(ctx)
        (row,) = certificates(ctx)
        kept = {
            oid: dataclasses.replace(c, clearance=c.clearance / 2)
            for oid, c in decode(row.clearances).items()
        }  # smaller than measured, so still true: a re-measure would overwrite them
        with ctx.sessions() as session, session.begin():
            session.execute(
                sa.update(TrajectoryCertificate).values(envelope=None, clearances=encode(kept))
            )
    with context(url, certificate_audit=True) as other:
        answer = ask(other, 0.03, 0.97)
        assert answer.memo is MemoUse.CERTIFICATE
        (after,) = certificates(other)
    assert after.envelope is not None and len(after.envelope) % 32 == 0
    assert {oid: c.clearance for oid, c in decode(after.clearances).items()} == {
        oid: c.clearance for oid, c in kept.items()
    }


def test_the_certificates_kept_in_memory_are_bounded_in_bytes() -> None:
    """Each certificate counts its digests, clearances and envelope (one the writer has yet to
    measure at its bounds): past the budget, the least recently used go."""
    envelope = Envelope(np.zeros((40, 3)), np.ones(40))
    clearance = ObjectClearance("s" * 64, np.eye(4), 0.05)
    read = Certified(frozenset({"d" * 64}), read={"box": clearance}, read_envelope=envelope)
    assert footprint(read) == 120 + 480 + 40 * 32
    pending = CertificateWrite(1, CertificateKey("v", "s", "p"), frozenset({"d" * 64}))
    pending = dataclasses.replace(pending, clearances=ClearanceJob(lambda: ({}, None)))
    assert footprint(pending.known()) == 120 + 480 + 512 * 32  # at its bounds
    store = CertificateStore(max_bytes=3 * footprint(pending.known()))
    for tid in range(1, 5):
        store.put(dataclasses.replace(pending, trajectory_id=tid))
    assert len(store) == 3
