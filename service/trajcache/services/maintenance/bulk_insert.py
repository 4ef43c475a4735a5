"""Writing imported trajectories in batches: one multi-row INSERT per batch, not one per row.

Rows are keyed by model and content hash, as the table's unique constraint keys them. A batch
is written with `INSERT … ON CONFLICT (model_id, content_hash) DO NOTHING RETURNING id`: a row
already stored (before the import, or by an earlier batch of it) is not returned and counts as
a duplicate; a row repeated inside one batch is dropped before the INSERT and counts the same.
On PostgreSQL a batch is copied (COPY, the driver's compiled path) into a temporary table of
the transaction and inserted from there with one `INSERT … SELECT … ON CONFLICT DO NOTHING`: a
VALUES list of 25 parameters a row costs more to build and parse than the rows cost to insert.
The writer never commits: the importer's one transaction holds every batch. The rows a batch
inserted (their ids read back by model and content hash) go to `inserted_fn`, which writes what
belongs with them in the same transaction (their end poses). `finish` writes the last batch and
one commit-log row per batch (its lowest and highest new id), the transaction's last writes: a
log id taken at the first batch of a long import would keep replicas waiting on it as a gap for
the whole import, longer than they wait (`db.commit_log`).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from typing import Any

import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from trajcache.db import models as tables
from trajcache.db.commit_log import log_commits

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

_KEY_SET = frozenset(_KEYS)
InsertedFn = Callable[[Session, list[dict[str, Any]]], None]  # the new rows, each with its id


class BatchWriter:
    """Collects rows (`add`) and inserts them a batch at a time (`flush`, at `batch_rows`)."""

    def __init__(
        self,
        session: Session,
        *,
        batch_rows: int = DEFAULT_BATCH_ROWS,
        inserted_fn: InsertedFn | None = None,
    ) -> None:
        self.session = session
        self.inserted_fn = inserted_fn
        self.batch_rows = max(1, batch_rows)
        self.inserted = 0
        self.duplicates = 0
        self._pending: dict[tuple[str, str], dict[str, Any]] = {}
        self._dialect = session.get_bind().dialect.name
        self._statement = _insert_statement(self._dialect)
        self._staged = False  # the PostgreSQL staging table exists
        self._ranges: list[tuple[int, int]] = []  # each batch's new ids, lowest and highest

    def add(self, values: Mapping[str, Any]) -> None:
        """Queue one row (the columns of `_KEYS`; missing ones are null)."""
        key = (values["model_id"], values["content_hash"])
        if key in self._pending:
            self.duplicates += 1
            return
        if _KEY_SET.issubset(values):
            self._pending[key] = dict(values)
        else:
            self._pending[key] = {name: values.get(name) for name in _KEYS}
        if len(self._pending) >= self.batch_rows:
            self.flush()

    def flush(self) -> None:
        """Insert the queued rows (inside the session's transaction)."""
        if not self._pending:
            return
        rows = list(self._pending.values())
        self._pending.clear()
        if self._dialect == "postgresql":
            keys = _staged_insert(self.session, rows, first=not self._staged)
            self._staged = True
        elif self._statement is None:
            keys = [key for row in rows if (key := _insert_one(self.session, row)) is not None]
        else:
            keys = [tuple(r) for r in self.session.connection().execute(self._statement, rows)]
        self.inserted += len(keys)
        self.duplicates += len(rows) - len(keys)
        if keys:
            ids = [int(k[0]) for k in keys]
            self._ranges.append((min(ids), max(ids)))
        if self.inserted_fn is not None and keys:
            by_key = {(row["model_id"], row["content_hash"]): row for row in rows}
            new = [{**by_key[(m, h)], "id": int(i)} for i, m, h in keys]
            self.inserted_fn(self.session, new)

    def finish(self) -> None:
        """Insert the queued rows and log every batch's ids (`db.commit_log`); the caller
        commits next."""
        self.flush()
        log_commits(self.session, self._ranges)
        self._ranges.clear()


def _insert_statement(dialect: str) -> sa.Insert | None:
    """The batch INSERT of PostgreSQL and SQLite; None elsewhere (one savepoint per row)."""
    if dialect not in ("postgresql", "sqlite"):
        return None
    insert = postgresql.insert if dialect == "postgresql" else sqlite.insert
    return (
        insert(_TABLE)
        .on_conflict_do_nothing(index_elements=["model_id", "content_hash"])
        .returning(_TABLE.c.id, _TABLE.c.model_id, _TABLE.c.content_hash)
    )


_Key = tuple[Any, ...]  # id, model_id, content_hash of an inserted row


def _insert_one(session: Session, row: dict[str, Any]) -> _Key | None:
    """The key of the row once inserted, None if it was already there (other databases)."""
    key = (_TABLE.c.model_id == row["model_id"]) & (_TABLE.c.content_hash == row["content_hash"])
    if session.execute(sa.select(_TABLE.c.id).where(key)).first() is not None:
        return None
    session.execute(sa.insert(_TABLE), [row])
    new_id = session.execute(sa.select(_TABLE.c.id).where(key)).scalar_one()
    return new_id, row["model_id"], row["content_hash"]


_STAGE = "trajcache_import_batch"  # a temporary table of the import's transaction


def _staged_insert(session: Session, rows: list[dict[str, Any]], first: bool) -> list[_Key]:
    """Insert `rows` on PostgreSQL: COPY into a temporary table, then one INSERT … SELECT …
    ON CONFLICT DO NOTHING; the keys of the new ones."""
    names = ", ".join(_KEYS)
    raw = session.connection().connection.driver_connection
    assert raw is not None  # a live connection of the session's transaction
    with raw.cursor() as cursor:
        if first:  # dropped at the end of the transaction, as the import's rows commit
            cursor.execute(
                f"CREATE TEMPORARY TABLE {_STAGE} ON COMMIT DROP AS "
                f"SELECT {names} FROM {_TABLE.name} WITH NO DATA"
            )
        else:
            cursor.execute(f"TRUNCATE {_STAGE}")
        with cursor.copy(f"COPY {_STAGE} ({names}) FROM STDIN") as copy:
            for row in rows:
                values = [row[k] for k in _KEYS]
                for i in _JSON_AT:
                    values[i] = json.dumps(values[i])
                copy.write_row(values)
        cursor.execute(
            f"INSERT INTO {_TABLE.name} ({names}) SELECT {names} FROM {_STAGE} "
            "ON CONFLICT (model_id, content_hash) DO NOTHING RETURNING id, model_id, content_hash"
        )
        return [tuple(r) for r in cursor.fetchall()]


_JSON_AT = [i for i, name in enumerate(_KEYS) if isinstance(_TABLE.c[name].type, sa.JSON)]
