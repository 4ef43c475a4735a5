"""Writing imported trajectories in batches: one multi-row INSERT per batch, not one per row.

Rows are keyed by model and content hash, as the table's unique constraint keys them. A batch
is written with `INSERT … ON CONFLICT (model_id, content_hash) DO NOTHING RETURNING id`: a row
already stored (before the import, or by an earlier batch of it) is not returned and counts as
a duplicate; a row repeated inside one batch is dropped before the INSERT and counts the same.
The writer never commits: the importer's one transaction holds every batch.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from trajcache.db import models as tables

DEFAULT_BATCH_ROWS = 1000
_TABLE: sa.Table = tables.Trajectory.__table__  # type: ignore[assignment]
# Every row of a batch carries the same keys (an executemany needs one statement shape).
_KEYS = (
    "model_id",
    "source",
    "robot_id",
    "states",
    "n_states",
    "dof",
    "start",
    "goal",
    "start_x",
    "start_y",
    "goal_x",
    "goal_y",
    "scene_hash",
    "env",
    "content_hash",
    "planning_time_ms",
    "hits",
    "failures",
    "consecutive_failures",
    "real_validations",
    "last_used_at",
    "last_validated_at",
    "last_real_validated_at",
    "created_at",
    "quality_pending",
)


class BatchWriter:
    """Collects rows (`add`) and inserts them a batch at a time (`flush`, at `batch_rows`)."""

    def __init__(self, session: Session, *, batch_rows: int = DEFAULT_BATCH_ROWS) -> None:
        self.session = session
        self.batch_rows = max(1, batch_rows)
        self.inserted = 0
        self.duplicates = 0
        self._pending: dict[tuple[str, str], dict[str, Any]] = {}
        self._statement = _insert_statement(session.get_bind().dialect.name)

    def add(self, values: Mapping[str, Any]) -> None:
        """Queue one row (the columns of `_KEYS`; missing ones are null)."""
        key = (values["model_id"], values["content_hash"])
        if key in self._pending:
            self.duplicates += 1
            return
        self._pending[key] = {name: values.get(name) for name in _KEYS}
        if len(self._pending) >= self.batch_rows:
            self.flush()

    def flush(self) -> None:
        """Insert the queued rows (inside the session's transaction)."""
        if not self._pending:
            return
        rows = list(self._pending.values())
        self._pending.clear()
        if self._statement is None:
            new = sum(_insert_one(self.session, row) for row in rows)
        else:
            new = len(self.session.connection().execute(self._statement, rows).all())
        self.inserted += new
        self.duplicates += len(rows) - new


def _insert_statement(dialect: str) -> sa.Insert | None:
    """The batch INSERT of PostgreSQL and SQLite; None elsewhere (one savepoint per row)."""
    if dialect not in ("postgresql", "sqlite"):
        return None
    insert = postgresql.insert if dialect == "postgresql" else sqlite.insert
    return (
        insert(_TABLE)
        .on_conflict_do_nothing(index_elements=["model_id", "content_hash"])
        .returning(_TABLE.c.id)
    )


def _insert_one(session: Session, row: dict[str, Any]) -> int:
    """1 if the row was inserted, 0 if it was already there (other databases)."""
    key = (_TABLE.c.model_id == row["model_id"]) & (_TABLE.c.content_hash == row["content_hash"])
    if session.execute(sa.select(_TABLE.c.id).where(key)).first() is not None:
        return 0
    session.execute(sa.insert(_TABLE), [row])
    return 1
