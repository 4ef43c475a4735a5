"""Writing and pruning the trajectory commit log (`TrajectoryCommit`) and the tombstones of
deleted trajectories (`TrajectoryTombstone`).

Every transaction that inserts trajectories logs the id range of each write, in that same
transaction and as its last write before the commit: a log row's id is then taken moments before
it becomes visible, so replicas wait for it as a gap only that long (see
`services.catalog.index_store`). Pruning deletes a prefix of the log by id and keeps the newest
row always: a replica compares its high-water mark with the oldest row left, and a hole in the
middle, or an empty log, would hide that rows were pruned. Tombstones are pruned the same way,
by the time of the deletion, and a replica checks their oldest id the same way.
"""

from __future__ import annotations

from collections.abc import Iterable
from datetime import datetime
from typing import cast

import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db.models import TrajectoryCommit, TrajectoryTombstone, utcnow

_LOG = cast(sa.Table, TrajectoryCommit.__table__)
# Core statements, built once: the ORM's insert cost a planned answer 0.3 ms more per row.
_INSERT = sa.insert(_LOG)
_INSERT_RETURNING = sa.insert(_LOG).returning(_LOG.c.id)


def log_commits(session: Session, ranges: Iterable[tuple[int, int]]) -> None:
    """Add one log row per (first id, last id) range, in the session's transaction."""
    now = utcnow()
    rows = [{"first_id": a, "last_id": b, "created_at": now} for a, b in ranges]
    if rows:
        session.connection().execute(_INSERT, rows)


def log_commit(session: Session, first_id: int, last_id: int) -> int:
    """Add one log row for the range in the session's transaction; its id."""
    row = {"first_id": first_id, "last_id": last_id, "created_at": utcnow()}
    return int(session.connection().execute(_INSERT_RETURNING, row).scalar_one())


def prune_commit_log(session: Session, *, before: datetime) -> int:
    """Delete the log rows below the first one created at or after `before` (all but the
    newest when none is); commit; how many went.

    What is left is a suffix of the log by id, so a replica whose high-water mark lies below
    the oldest id left knows it missed rows, even if clocks disagree about `created_at`."""
    return _prune_prefix(session, TrajectoryCommit.id, TrajectoryCommit.created_at, before)


def prune_tombstones(session: Session, *, before: datetime) -> int:
    """Delete the tombstones below the first one made at or after `before` (all but the
    newest when none is); commit; how many went. What is left is a suffix by id, as for the
    log (`prune_commit_log`)."""
    return _prune_prefix(session, TrajectoryTombstone.id, TrajectoryTombstone.deleted_at, before)


def _prune_prefix(
    session: Session,
    id_column: sa.orm.InstrumentedAttribute[int],
    time_column: sa.orm.InstrumentedAttribute[datetime],
    before: datetime,
) -> int:
    table = id_column.class_
    recent = sa.select(sa.func.min(id_column)).where(time_column >= before)
    newest = sa.select(sa.func.max(id_column))
    keep_from = sa.func.coalesce(recent.scalar_subquery(), newest.scalar_subquery())
    deleted = session.execute(sa.delete(table).where(id_column < keep_from))
    session.commit()
    return int(deleted.rowcount or 0)  # type: ignore[attr-defined]
