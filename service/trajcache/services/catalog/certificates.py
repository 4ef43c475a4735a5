"""Certificates of stored trajectories (`geometry/validation/certificates.py`), where every
replica finds them: the `trajectory_certificates` table, read through a per-process LRU.

A certificate only ever grows (more object digests) or disappears (with its trajectory, or when
the certifier or the settings change its stamp), and every digest in it was proved, so a copy
that is older than the table is still true: the LRU needs no invalidation. The plan flow reads
one when the validation memo does not already know a candidate's interior, and writes them
through the plan records (`services.bookkeeping.record_batch`), after the answer has gone out.

A certificate written after a scene change also keeps its objects' clearances (`clearances`:
how far the interior stayed from each, by id) and its interior's swept envelope (`envelope`,
`geometry/validation/envelope.py`: it depends on the path and the model variant alone, so it is
measured once per certificate and carried over), measured by the record writer before its
transaction (`ClearanceJob`); a process that wrote it knows them once they are measured.

Bounds: at most `MAX_OBJECTS` digests, `MAX_KEPT` clearances and `MAX_BALLS` envelope balls
per certificate, `PER_TRAJECTORY` certificates per trajectory (the most recently written), and
only the current stamp's; in each process's LRU, `CACHE_BYTES` of them (64 MiB; an envelope
alone may take 16 KiB) besides its count.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.engine import Connection
from sqlalchemy.orm import Session

from trajcache.core.lru import LRU
from trajcache.db.models import Trajectory, TrajectoryCertificate
from trajcache.geometry.validation.certificates import CertificateKey, ObjectClearance
from trajcache.geometry.validation.envelope import MAX_BALLS, Envelope
from trajcache.geometry.validation.object_clearance import MAX_KEPT

__all__ = [
    "CertificateStore",
    "CertificateWrite",
    "Certified",
    "ClearanceJob",
    "footprint",
    "write_certificates",
]

PER_TRAJECTORY = 8
CACHE_BYTES = 64 << 20  # the per-process LRU's budget (`footprint`)
_DIGEST_BYTES = 120  # a hex SHA-256 digest as a Python str, with its slot in a frozenset
_CLEARANCE_BYTES = 480  # an ObjectClearance: its shape digest, 4×4 pose array and dict slot
_BALL_BYTES = 32  # an envelope ball: x, y, z, r as float64
_C = TrajectoryCertificate
_log = logging.getLogger(__name__)
Clearances = Mapping[str, ObjectClearance]


Measure = Callable[[], tuple[Clearances, Envelope | None]]


class ClearanceJob:
    """A certificate's object clearances and swept envelope, measured once, by the record
    writer (`compute` gives what it measured: clearances, and the envelope unless `envelope`,
    the one the certificate holds already, is given)."""

    def __init__(
        self, compute: Measure, kept: Clearances | None = None, envelope: Envelope | None = None
    ) -> None:
        self._compute: Measure | None = compute
        self._kept = dict(kept or {})  # earlier ones, for objects not measured now
        self._values: Clearances | None = None
        self.envelope = envelope

    def run(self) -> Clearances:
        """Measure (the first call); a failure is logged and leaves the earlier ones."""
        if self._compute is not None:
            compute, self._compute = self._compute, None
            measured: Clearances = {}
            try:
                measured, envelope = compute()
                self.envelope = self.envelope or envelope
            except Exception:
                _log.exception("object clearances could not be measured")
            merged = {**self._kept, **measured}
            self._values = dict(list(merged.items())[-MAX_KEPT:])
        return self._values or {}

    @property
    def ready(self) -> Clearances:
        """What was measured so far (nothing before `run`)."""
        return self._values or {}


@dataclass(frozen=True)
class CertificateWrite:
    """A certificate to keep: the trajectory, what it is about, every digest it holds, and its
    objects' clearances (measured by the writer, or carried over)."""

    trajectory_id: int
    key: CertificateKey
    objects: frozenset[str]
    clearances: ClearanceJob | None = None

    def known(self) -> Certified:
        return Certified(self.objects, self.clearances)


@dataclass(frozen=True)
class Certified:
    """What a certificate holds: object digests, object clearances by id, and its swept
    envelope."""

    objects: frozenset[str] = frozenset()
    job: ClearanceJob | None = field(default=None, repr=False)
    read: Clearances | None = None
    read_envelope: Envelope | None = None

    @property
    def clearances(self) -> Clearances:
        """The clearances known now (none while the writer has not measured them)."""
        if self.read is not None:
            return self.read
        return self.job.ready if self.job is not None else {}

    @property
    def envelope(self) -> Envelope | None:
        """The swept envelope known now (none while the writer has not measured it)."""
        if self.read_envelope is not None:
            return self.read_envelope
        return self.job.envelope if self.job is not None else None


class CertificateStore:
    """The certificates this process has read or written, by trajectory and key, at most
    `capacity` of them and `max_bytes` of their contents (`footprint`)."""

    def __init__(self, capacity: int = 16384, max_bytes: int = CACHE_BYTES) -> None:
        self._known: LRU[tuple[int, CertificateKey], Certified] = LRU(
            capacity=capacity, max_size=max_bytes, size_fn=footprint
        )

    def get(self, session: Session, trajectory_id: int, key: CertificateKey) -> Certified:
        """What is certified for `key` on the trajectory (no digests: nothing)."""
        known = self._known.get((trajectory_id, key))
        if known is not None:
            return known
        row = session.execute(
            sa.select(_C.objects, _C.clearances, _C.envelope).where(
                _C.trajectory_id == trajectory_id,
                _C.variant == key.variant,
                _C.stamp == key.stamp,
                _C.path == key.path,
            )
        ).first()
        if row is None:
            return Certified()
        envelope = Envelope.from_bytes(row[2]) if row[2] else None
        objects = frozenset(str(d) for d in row[0])
        found = Certified(objects, read=decode(row[1]), read_envelope=envelope)
        self._known.put((trajectory_id, key), found)
        return found

    def put(self, write: CertificateWrite) -> None:
        """Know a certificate this process is about to write."""
        self._known.put((write.trajectory_id, write.key), write.known())

    def clear(self) -> None:
        """Forget every certificate read (the table keeps them)."""
        self._known.clear()

    def __len__(self) -> int:
        return len(self._known)


def footprint(certified: Certified) -> int:
    """Bytes a certificate holds in memory, about: its digests, clearances and envelope; one the
    writer has yet to measure counted at its bounds (`MAX_BALLS`), so the cache never grows past
    its budget when the measures arrive."""
    objects = len(certified.objects)
    if certified.job is not None:
        clearances, balls = min(objects, MAX_KEPT), MAX_BALLS
    else:
        envelope = certified.read_envelope
        clearances, balls = len(certified.read or {}), len(envelope.radii) if envelope else 0
    return objects * _DIGEST_BYTES + clearances * _CLEARANCE_BYTES + balls * _BALL_BYTES


def write_certificates(conn: Connection, writes: Iterable[CertificateWrite], at: datetime) -> None:
    """Replace each certificate with its new digests, in the caller's transaction; a trajectory
    deleted meanwhile gets none. Older stamps and certificates beyond `PER_TRAJECTORY` go."""
    for write in writes:
        key, tid = write.key, write.trajectory_id
        same = (_C.trajectory_id == tid) & (_C.variant == key.variant) & (_C.path == key.path)
        conn.execute(sa.delete(_C).where(same & (_C.stamp == key.stamp)))
        conn.execute(sa.delete(_C).where((_C.trajectory_id == tid) & (_C.stamp != key.stamp)))
        measured = write.clearances.run() if write.clearances else None  # and the envelope
        values: dict[str, Any] = {
            "trajectory_id": tid,
            "variant": key.variant,
            "stamp": key.stamp,
            "path": key.path,
            "objects": sorted(write.objects),
            "clearances": encode(measured) if measured is not None else None,
            "envelope": _envelope_bytes(write.clearances),
            "updated_at": at,
        }
        source = sa.select(
            *(sa.literal(v, type_=_C.__table__.c[k].type) for k, v in values.items())
        )
        exists = sa.exists().where(Trajectory.id == tid)
        conn.execute(sa.insert(_C).from_select(list(values), source.where(exists)))
        newest = (
            sa.select(_C.id)
            .where(_C.trajectory_id == tid)
            .order_by(_C.updated_at.desc(), _C.id.desc())
            .limit(PER_TRAJECTORY)
        )
        conn.execute(
            sa.delete(_C).where(_C.trajectory_id == tid, _C.id.not_in(newest.scalar_subquery()))
        )


def _envelope_bytes(job: ClearanceJob | None) -> bytes | None:
    """The stored form of a measured envelope (after `job.run`), or None."""
    envelope = job.envelope if job is not None else None
    return envelope.to_bytes() if envelope is not None else None


def encode(clearances: Clearances) -> dict[str, list[Any]] | None:
    """JSON of object clearances: id → [shape digest, pose (its top 3 rows), clearance]."""
    if not clearances:
        return None
    return {
        oid: [c.shape, [float(v) for v in c.pose[:3].ravel()], float(c.clearance)]
        for oid, c in clearances.items()
    }


def decode(stored: Mapping[str, list[Any]] | None) -> Clearances:
    """Object clearances from their JSON (`encode`)."""
    out: dict[str, ObjectClearance] = {}
    for oid, (shape, pose, clearance) in (stored or {}).items():
        matrix = np.eye(4)
        matrix[:3] = np.asarray(pose, dtype=float).reshape(3, 4)
        out[str(oid)] = ObjectClearance(str(shape), matrix, float(clearance))
    return out
