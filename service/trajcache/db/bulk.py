"""Plain rows written in bulk inside a session's transaction: COPY on PostgreSQL, one
executemany elsewhere.

For rows that need no defaults, conflicts or returned ids (the end-pose index of new
trajectories): PostgreSQL's COPY (the driver's compiled path) takes them as they are, where an
INSERT pipeline of one statement per row parses and plans each. Values go as the driver adapts
them (numbers, strings, None).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

__all__ = ["insert_rows"]


def insert_rows(
    session: Session, table: sa.Table, names: Sequence[str], rows: Sequence[Sequence[Any]]
) -> None:
    """Insert `rows` (tuples of the columns `names`, in order) into `table`, in the session's
    transaction."""
    if not rows:
        return
    connection = session.connection()
    if connection.dialect.name != "postgresql":
        keyed = [dict(zip(names, row, strict=True)) for row in rows]
        connection.execute(_insert(table), keyed)
        return
    quote = connection.dialect.identifier_preparer.quote  # `end` is a reserved word
    columns = ", ".join(quote(name) for name in names)
    raw = connection.connection.driver_connection
    assert raw is not None  # a live connection of the session's transaction
    with (
        raw.cursor() as cursor,
        cursor.copy(f"COPY {quote(table.name)} ({columns}) FROM STDIN") as copy,
    ):
        for row in rows:
            copy.write_row(row)


@functools.cache
def _insert(table: sa.Table) -> sa.Insert:
    """The table's INSERT, built once: a new statement's cache key is computed on each run."""
    return sa.insert(table)
