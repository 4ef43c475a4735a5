"""Certificates of stored trajectories (`geometry/validation/certificates.py`), where every
replica finds them: the `trajectory_certificates` table, read through a per-process LRU.

A certificate only ever grows (more object digests) or disappears (with its trajectory, or when
the certifier or the settings change its stamp), and every digest in it was proved, so a copy
that is older than the table is still true: the LRU needs no invalidation. The plan flow reads
one when the validation memo does not already know a candidate's interior, and writes them
through the plan records (`services.bookkeeping.record_batch`), after the answer has gone out.

Bounds: at most `MAX_OBJECTS` digests per certificate, `PER_TRAJECTORY` certificates per
trajectory (the most recently written), and only the current stamp's.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Connection
from sqlalchemy.orm import Session

from trajcache.core.lru import LRU
from trajcache.db.models import Trajectory, TrajectoryCertificate
from trajcache.geometry.validation.certificates import CertificateKey

__all__ = ["CertificateStore", "CertificateWrite", "write_certificates"]

PER_TRAJECTORY = 8
_C = TrajectoryCertificate


@dataclass(frozen=True)
class CertificateWrite:
    """A certificate to keep: the trajectory, what it is about, and every digest it holds."""

    trajectory_id: int
    key: CertificateKey
    objects: frozenset[str]


class CertificateStore:
    """The certificates this process has read or written, by trajectory and key."""

    def __init__(self, capacity: int = 16384) -> None:
        self._known: LRU[tuple[int, CertificateKey], frozenset[str]] = LRU(capacity=capacity)

    def get(self, session: Session, trajectory_id: int, key: CertificateKey) -> frozenset[str]:
        """The object digests certified for `key` on the trajectory (empty: none)."""
        known = self._known.get((trajectory_id, key))
        if known is not None:
            return known
        row = session.execute(
            sa.select(_C.objects).where(
                _C.trajectory_id == trajectory_id,
                _C.variant == key.variant,
                _C.stamp == key.stamp,
                _C.path == key.path,
            )
        ).first()
        if row is None:
            return frozenset()
        objects = frozenset(str(d) for d in row[0])
        self._known.put((trajectory_id, key), objects)
        return objects

    def put(self, write: CertificateWrite) -> None:
        """Know a certificate this process is about to write."""
        self._known.put((write.trajectory_id, write.key), write.objects)

    def clear(self) -> None:
        """Forget every certificate read (the table keeps them)."""
        self._known.clear()


def write_certificates(conn: Connection, writes: Iterable[CertificateWrite], at: datetime) -> None:
    """Replace each certificate with its new digests, in the caller's transaction; a trajectory
    deleted meanwhile gets none. Older stamps and certificates beyond `PER_TRAJECTORY` go."""
    for write in writes:
        key, tid = write.key, write.trajectory_id
        same = (_C.trajectory_id == tid) & (_C.variant == key.variant) & (_C.path == key.path)
        conn.execute(sa.delete(_C).where(same & (_C.stamp == key.stamp)))
        conn.execute(sa.delete(_C).where((_C.trajectory_id == tid) & (_C.stamp != key.stamp)))
        values: dict[str, Any] = {
            "trajectory_id": tid,
            "variant": key.variant,
            "stamp": key.stamp,
            "path": key.path,
            "objects": sorted(write.objects),
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
