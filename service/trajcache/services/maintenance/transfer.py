"""Moving a cache between deployments: the JSON Lines format, and export to it (import: `importer`).

One JSON object per line, in this order:

1. `{"type": "header", "format": "trajcache-export", "version": 3, "exported_at": ISO-8601,
   "filters": {...}}` — optional on import; a file of another format or a newer version is
   refused as a whole.
2. Per model, before its trajectories: `{"type": "model", "model_id", "name", "base",
   "joint_names", "urdf", "srdf", "joint_values", "files": [{"path", "sha256", "data": base64}],
   "acceleration_limits", "jerk_limits", "end_effector_link"}` (`srdf` and `joint_values`
   only when the model was registered with them). Import registers the model
   (same content → same id) unless it exists. Without model lines, every model must already be
   in the target database; a trajectory of an unknown model is rejected.
3. `{"type": "trajectory", "model_id", "states": [[...], ...], "source", "robot_id",
   "scene_hash", "env": {...}, "content_hash", "planning_time_ms", "created_at",
   "last_used_at", "last_validated_at", "last_real_validated_at", "hits", "failures",
   "consecutive_failures", "real_validations"}` — states ordered as the model's
   `state_names`; timestamps ISO-8601 (UTC) or null; `content_hash` (optional on import) is
   checked against the states.
4. `{"type": "cartesian_path", ...}` (version 3): the stored Cartesian paths, each after its
   model's line (`cartesian_transfer`: the format, and what import checks). They have no
   source nor creation time: an export filtered by source or age carries none.
5. `{"type": "end", "trajectories": N, "cartesian_paths": M}` (version 2): the last line, with
   the number of lines of each kind written (for information). A file of version 2 or later
   without it was cut short (a plain file can be cut at a line's end) and is refused as a
   whole, as is text after it.

Versions: 1 (trajcache up to the release that added background quality) has no end line;
importing it still works, without the cut-short check. 2 adds the end line, 3 the Cartesian
paths; every earlier version still imports.

Export streams: rows are read a batch at a time (a server-side cursor on PostgreSQL) and
written as they come, so its memory does not grow with the cache. Import is idempotent: a
trajectory is identified by its model and the hash of its states, so importing the same one
twice stores one row (the second is counted as a duplicate, its counters are not added). Every
trajectory is checked like a stored one (state count, length, finite values, joint limits); a
line that fails is rejected with its line number and reason, and the rest is imported. Rows are
written in batches (`bulk_insert`); their quality is computed afterwards, in the background
(`backfill`), and shows as pending until then. The import is one transaction: input that is
corrupt, truncated or empty (gzip that does not unpack to its end, text that is not UTF-8, a
line that is not JSON; see `reading`) refuses the whole import and stores nothing, and an
interrupted import stores nothing either, so it can simply be run again.
"""

from __future__ import annotations

import base64
import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db import models as tables
from trajcache.services.catalog.trajectories import SOURCES
from trajcache.services.errors import InvalidInputError, NotFoundError
from trajcache.services.maintenance.cartesian_transfer import cartesian_records

FORMAT = "trajcache-export"
FORMAT_VERSION = 3
EXPORT_BATCH_ROWS = 2000
_T = tables.Trajectory
COUNTERS = ("hits", "failures", "consecutive_failures", "real_validations")
TIMES = ("created_at", "last_used_at", "last_validated_at", "last_real_validated_at")


@dataclass(frozen=True)
class ExportFilter:
    """Which trajectories to export: models, sources, and created within an age window."""

    model_ids: tuple[str, ...] = ()
    sources: tuple[str, ...] = ()
    created_after: datetime | None = None
    created_before: datetime | None = None

    def conditions(self) -> list[sa.ColumnElement[bool]]:
        """WHERE conditions on the trajectories table."""
        out: list[sa.ColumnElement[bool]] = []
        if self.model_ids:
            out.append(_T.model_id.in_(self.model_ids))
        if self.sources:
            out.append(_T.source.in_(self.sources))
        if self.created_after is not None:
            out.append(_T.created_at >= self.created_after)
        if self.created_before is not None:
            out.append(_T.created_at < self.created_before)
        return out

    def selects_cartesian_paths(self) -> bool:
        """Cartesian paths have no source nor creation time: only a filter by model keeps them."""
        return not self.sources and self.created_after is None and self.created_before is None

    def as_dict(self) -> dict[str, Any]:
        """The filter as written into the header."""
        return {
            "model_ids": list(self.model_ids),
            "sources": list(self.sources),
            "created_after": _iso(self.created_after),
            "created_before": _iso(self.created_before),
        }


def _iso(value: datetime | None) -> str | None:
    return None if value is None else value.astimezone(UTC).isoformat()


def check_filter(session: Session, filt: ExportFilter) -> None:
    """Unknown models (404) and sources (422) are errors, not empty exports."""
    for source in filt.sources:
        if source not in SOURCES:
            raise InvalidInputError(f"source {source!r} must be one of {', '.join(SOURCES)}")
    for model_id in filt.model_ids:
        if session.get(tables.RobotModel, model_id) is None:
            raise NotFoundError(f"robot model {model_id!r} not found")


def count_exported(session: Session, filt: ExportFilter) -> int:
    """How many trajectories the filter selects."""
    stmt = sa.select(sa.func.count()).select_from(_T).where(*filt.conditions())
    return int(session.execute(stmt).scalar_one())


def model_record(session: Session, model_id: str) -> dict[str, Any]:
    """The model line of `model_id` (URDF and files included)."""
    row = session.get(tables.RobotModel, model_id)
    if row is None:
        raise NotFoundError(f"robot model {model_id!r} not found")
    files = session.execute(
        sa.select(tables.ModelFile.path, tables.ModelFile.sha256, tables.ModelFile.data)
        .where(tables.ModelFile.model_id == model_id)
        .order_by(tables.ModelFile.path)
    ).all()
    return {
        "type": "model",
        "model_id": row.id,
        "name": row.name,
        "base": row.base,
        "joint_names": list(row.joint_names),
        "urdf": row.urdf,
        **{k: v for k, v in (row.config or {}).items() if k in ("srdf", "joint_values")},
        "files": [
            {"path": p, "sha256": sha, "data": base64.b64encode(data).decode("ascii")}
            for p, sha, data in files
        ],
        "acceleration_limits": row.acceleration_limits,
        "jerk_limits": row.jerk_limits,
        "end_effector_link": row.end_effector_link,
    }


_EXPORTED = (
    _T.model_id,
    _T.states,
    _T.n_states,
    _T.dof,
    _T.source,
    _T.robot_id,
    _T.scene_hash,
    sa.cast(_T.env, sa.Text).label("env_text"),  # decoded only when not empty
    _T.content_hash,
    _T.planning_time_ms,
    *(getattr(_T, name) for name in TIMES),
    *(getattr(_T, name) for name in COUNTERS),
)


def trajectory_record(row: Any) -> dict[str, Any]:
    """The trajectory line of a stored row (an ORM row, or a row of `_EXPORTED`)."""
    states = np.frombuffer(row.states, dtype=tables.STATE_DTYPE).reshape(row.n_states, row.dof)
    record: dict[str, Any] = {
        "type": "trajectory",
        "model_id": row.model_id,
        "states": states.tolist(),
        "source": row.source,
        "robot_id": row.robot_id,
        "scene_hash": row.scene_hash,
        "env": _env(row),
        "content_hash": row.content_hash,
        "planning_time_ms": row.planning_time_ms,
    }
    for name in TIMES:
        record[name] = _iso(getattr(row, name))
    for name in COUNTERS:
        record[name] = int(getattr(row, name) or 0)
    return record


def _env(row: Any) -> dict[str, Any]:
    """The row's environment values; an empty one (most) is not decoded."""
    if not hasattr(row, "env_text"):
        return dict(row.env or {})
    text = row.env_text
    return {} if text is None or text == "{}" else dict(json.loads(text))


def export_records(
    *, session: Session, filt: ExportFilter, include_models: bool = True
) -> Iterator[dict[str, Any]]:
    """The header, each model's line and its trajectories (by model, then id), the Cartesian
    paths (after their model's line), the end line."""
    check_filter(session, filt)
    yield {
        "type": "header",
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "exported_at": _iso(datetime.now(UTC)),
        "filters": filt.as_dict(),
    }
    rows = session.execute(
        sa.select(*_EXPORTED)
        .where(*filt.conditions())
        .order_by(_T.model_id, _T.id)
        .execution_options(yield_per=EXPORT_BATCH_ROWS)
    )
    written: set[str] = set()
    count = paths = 0
    for row in rows:
        if include_models and row.model_id not in written:
            written.add(row.model_id)
            yield model_record(session, row.model_id)
        count += 1
        yield trajectory_record(row)
    if filt.selects_cartesian_paths():
        for record in cartesian_records(session, filt.model_ids):
            if include_models and record["model_id"] not in written:
                written.add(record["model_id"])
                yield model_record(session, record["model_id"])
            paths += 1
            yield record
    yield {"type": "end", "trajectories": count, "cartesian_paths": paths}


def dumps(record: Mapping[str, Any]) -> str:
    """One line of the export (no trailing newline)."""
    return json.dumps(record, separators=(",", ":"), allow_nan=False, ensure_ascii=False)
