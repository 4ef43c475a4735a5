"""Moving a cache between deployments: export to and import from JSON Lines.

One JSON object per line, in this order:

1. `{"type": "header", "format": "trajcache-export", "version": 1, "exported_at": ISO-8601,
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

Import is idempotent: a trajectory is identified by its model and the hash of its states, so
importing the same one twice stores one row (the second is counted as a duplicate, its
counters are not added). Every trajectory is checked like a stored one (state count, length,
finite values, joint limits); a line that fails is rejected with its line number and reason,
and the rest is imported. Rows are committed in batches, so an interrupted import can simply
be run again.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import json
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.core.config import Settings
from trajcache.db import models as tables
from trajcache.db.models import trajectory_content_hash
from trajcache.geometry.errors import GeometryError
from trajcache.geometry.model.kinematics import check_limits, check_states
from trajcache.geometry.model.robot import RobotModel
from trajcache.services.errors import InvalidInputError, NotFoundError, ServiceError
from trajcache.services.models import ModelRegistry, get_model, register_model
from trajcache.services.trajectories import SOURCES, store_trajectory

FORMAT = "trajcache-export"
FORMAT_VERSION = 1
MAX_LISTED_REJECTS = 1000
_T = tables.Trajectory
_COUNTERS = ("hits", "failures", "consecutive_failures", "real_validations")
_TIMES = ("created_at", "last_used_at", "last_validated_at", "last_real_validated_at")


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


def trajectory_record(row: tables.Trajectory) -> dict[str, Any]:
    """The trajectory line of a stored row."""
    record: dict[str, Any] = {
        "type": "trajectory",
        "model_id": row.model_id,
        "states": row.states_array().tolist(),
        "source": row.source,
        "robot_id": row.robot_id,
        "scene_hash": row.scene_hash,
        "env": dict(row.env or {}),
        "content_hash": row.content_hash,
        "planning_time_ms": row.planning_time_ms,
    }
    for name in _TIMES:
        record[name] = _iso(getattr(row, name))
    for name in _COUNTERS:
        record[name] = int(getattr(row, name) or 0)
    return record


def export_records(
    *, session: Session, filt: ExportFilter, include_models: bool = True
) -> Iterator[dict[str, Any]]:
    """The header, then each model's line and its trajectories (by model, then id)."""
    check_filter(session, filt)
    yield {
        "type": "header",
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "exported_at": _iso(datetime.now(UTC)),
        "filters": filt.as_dict(),
    }
    rows = session.scalars(
        sa.select(_T)
        .where(*filt.conditions())
        .order_by(_T.model_id, _T.id)
        .execution_options(yield_per=500)
    )
    current: str | None = None
    for row in rows:
        if include_models and row.model_id != current:
            current = row.model_id
            yield model_record(session, row.model_id)
        yield trajectory_record(row)


def dumps(record: Mapping[str, Any]) -> str:
    """One line of the export (no trailing newline)."""
    return json.dumps(record, separators=(",", ":"), allow_nan=False, ensure_ascii=False)


@dataclass(frozen=True)
class Rejected:
    """A line that was not imported, and why."""

    line: int
    reason: str


@dataclass
class ImportReport:
    """What an import did."""

    lines: int = 0
    models_created: int = 0
    models_existing: int = 0
    inserted: int = 0
    duplicates: int = 0
    rejected_count: int = 0
    rejected: list[Rejected] = field(default_factory=list)  # the first MAX_LISTED_REJECTS

    def reject(self, line: int, reason: str) -> None:
        """Record a rejected line."""
        self.rejected_count += 1
        if len(self.rejected) < MAX_LISTED_REJECTS:
            self.rejected.append(Rejected(line, reason))


class _LineError(Exception):
    """A line that cannot be imported (the message says why)."""


class ImportFormatError(InvalidInputError):
    """The input is not an export this version reads (the whole import is refused)."""


def _reject_constant(token: str) -> Any:
    raise _LineError(f"{token} is not a valid number (values must be finite)")


def _timestamp(record: Mapping[str, Any], name: str) -> datetime | None:
    value = record.get(name)
    if value is None:
        return None
    if not isinstance(value, str):
        raise _LineError(f"{name} must be an ISO-8601 timestamp or null")
    try:
        parsed = datetime.fromisoformat(value)
    except ValueError:
        raise _LineError(f"{name} {value[:40]!r} is not an ISO-8601 timestamp") from None
    return parsed if parsed.tzinfo is not None else parsed.replace(tzinfo=UTC)


def _counter(record: Mapping[str, Any], name: str) -> int:
    value = record.get(name, 0)
    if value is None:
        return 0
    if isinstance(value, bool) or not isinstance(value, int) or value < 0 or value > 2**31 - 1:
        raise _LineError(f"{name} must be a non-negative integer, got {value!r:.40}")
    return value


class Importer:
    """Imports export lines one by one into a database session (see the module docstring)."""

    def __init__(
        self,
        *,
        session: Session,
        registry: ModelRegistry,
        settings: Settings,
        source: str | None = None,
        batch_size: int = 500,
    ) -> None:
        if source is not None and source not in SOURCES:
            raise InvalidInputError(f"source {source!r} must be one of {', '.join(SOURCES)}")
        self.session = session
        self.registry = registry
        self.settings = settings
        self.source = source
        self.batch_size = batch_size
        self.report = ImportReport()
        self._model_ids: dict[str, str] = {}  # id in the file -> id in this database
        self._models: dict[str, RobotModel] = {}
        self._pending = 0

    def feed(self, line_no: int, text: str) -> None:
        """Import one line (blank lines are skipped)."""
        if not text.strip():
            return
        self.report.lines += 1
        try:
            record = json.loads(text, parse_constant=_reject_constant)
            if not isinstance(record, dict):
                raise _LineError("a line must be a JSON object")
            kind = record.get("type")
            if kind == "header":
                self._header(record, line_no)
            elif kind == "model":
                self._model(record)
            elif kind == "trajectory":
                self._trajectory(record)
            else:
                raise _LineError(f"unknown line type {kind!r:.40}")
        except json.JSONDecodeError as exc:
            self.report.reject(line_no, f"not valid JSON: {exc.msg} (column {exc.colno})")
        except RecursionError:
            self.report.reject(line_no, "not valid JSON: it nests too deeply")
        except ImportFormatError:
            raise
        except (_LineError, GeometryError, ServiceError) as exc:
            self.report.reject(line_no, str(exc)[:500])

    def finish(self) -> ImportReport:
        """Commit what is pending and return the report."""
        self.session.commit()
        return self.report

    def _header(self, record: Mapping[str, Any], line_no: int) -> None:
        if record.get("format") != FORMAT:
            raise ImportFormatError(
                f"line {line_no}: not a trajcache export (format {record.get('format')!r:.60})"
            )
        version = record.get("version")
        if not isinstance(version, int) or version > FORMAT_VERSION:
            raise ImportFormatError(
                f"line {line_no}: export format version {version!r:.20} is newer than this "
                f"trajcache reads ({FORMAT_VERSION}); upgrade trajcache"
            )

    def _model(self, record: Mapping[str, Any]) -> None:
        file_id = record.get("model_id")
        urdf = record.get("urdf")
        if not isinstance(file_id, str) or not isinstance(urdf, str):
            raise _LineError("a model line needs model_id and urdf strings")
        files: dict[str, bytes] = {}
        for i, entry in enumerate(record.get("files") or []):
            try:
                data = base64.b64decode(entry["data"], validate=True)
                path = str(entry["path"])
            except (KeyError, TypeError, binascii.Error):
                raise _LineError(f"files[{i}] needs a path and base64 data") from None
            if entry.get("sha256") not in (None, hashlib.sha256(data).hexdigest()):
                raise _LineError(f"files[{i}] ({path}): sha256 does not match its data")
            files[path] = data
        self.session.commit()  # registration commits on its own: end the batch first
        model, created = register_model(
            session=self.session,
            registry=self.registry,
            urdf=urdf,
            files=files,
            base=str(record.get("base", "fixed")),
            joint_names=record.get("joint_names"),
            srdf=_optional_text(record.get("srdf"), "srdf"),
            joint_values=_joint_values(record.get("joint_values")),
            name=record.get("name"),
            max_urdf_bytes=self.settings.max_urdf_bytes,
            acceleration_limits=record.get("acceleration_limits"),
            jerk_limits=record.get("jerk_limits"),
            end_effector_link=record.get("end_effector_link"),
        )
        if created:
            self.report.models_created += 1
        else:
            self.report.models_existing += 1
        self._model_ids[file_id] = model.model_id
        self._models[model.model_id] = model

    def _model_for(self, file_id: Any) -> RobotModel:
        if not isinstance(file_id, str) or not file_id:
            raise _LineError("a trajectory line needs a model_id")
        model_id = self._model_ids.get(file_id, file_id)
        model = self._models.get(model_id)
        if model is None:
            try:
                model = get_model(session=self.session, registry=self.registry, model_id=model_id)
            except NotFoundError:
                raise _LineError(
                    f"model {file_id!r} is not in this database and the file has no model "
                    "line for it (export with models included)"
                ) from None
            self._models[model_id] = model
        return model

    def _trajectory(self, record: Mapping[str, Any]) -> None:
        model = self._model_for(record.get("model_id"))
        states = check_states(model, _states(record), name="state")
        check_limits(model, states, name="state")
        expected = record.get("content_hash")
        if expected is not None and expected != trajectory_content_hash(states):
            raise _LineError("content_hash does not match the states")
        times = {name: _timestamp(record, name) for name in _TIMES}
        counters = {name: _counter(record, name) for name in _COUNTERS}
        new_id, created = store_trajectory(
            session=self.session,
            model=model,
            states=states,
            source=self.source or _optional_str(record, "source") or "import",
            robot_id=_optional_str(record, "robot_id"),
            scene_hash=_optional_str(record, "scene_hash"),
            env=_env(record),
            planning_time_ms=_optional_number(record, "planning_time_ms"),
            max_states=self.settings.max_trajectory_states,
            commit=False,
        )
        if not created:
            self.report.duplicates += 1
            return
        values: dict[str, Any] = dict(counters)
        values.update({k: v for k, v in times.items() if v is not None})
        self.session.execute(sa.update(_T).where(_T.id == new_id).values(**values))
        self.report.inserted += 1
        self._pending += 1
        if self._pending >= self.batch_size:
            self.session.commit()
            self._pending = 0


def _states(record: Mapping[str, Any]) -> list[Any]:
    states = record.get("states")
    if not isinstance(states, list) or not all(isinstance(s, list) for s in states):
        raise _LineError("states must be a list of states (lists of numbers)")
    if len(states) < 2:
        raise _LineError(f"a trajectory needs at least 2 states, got {len(states)}")
    return states


def _optional_str(record: Mapping[str, Any], name: str) -> str | None:
    value = record.get(name)
    if value is not None and not isinstance(value, str):
        raise _LineError(f"{name} must be a string or null")
    return value


def _optional_number(record: Mapping[str, Any], name: str) -> float | None:
    value = record.get(name)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _LineError(f"{name} must be a number or null")
    return float(value)


def _env(record: Mapping[str, Any]) -> Mapping[str, Any]:
    env = record.get("env") or {}
    if not isinstance(env, Mapping):
        raise _LineError("env must be an object of names to numbers")
    return env


def import_lines(
    *,
    session: Session,
    registry: ModelRegistry,
    settings: Settings,
    lines: Iterable[str],
    source: str | None = None,
) -> ImportReport:
    """Import export lines (see the module docstring); the report lists rejected lines."""
    importer = Importer(session=session, registry=registry, settings=settings, source=source)
    try:
        for number, text in enumerate(lines, start=1):
            importer.feed(number, text)
    except BaseException:
        session.rollback()
        raise
    return importer.finish()


def _optional_text(value: Any, what: str) -> str | None:
    if value is not None and not isinstance(value, str):
        raise _LineError(f"{what} must be a string")
    return value


def _joint_values(value: Any) -> dict[str, float] | str | None:
    if value is None or isinstance(value, str):
        return value
    if not isinstance(value, Mapping) or not all(
        isinstance(k, str) and isinstance(v, int | float) and not isinstance(v, bool)
        for k, v in value.items()
    ):
        raise _LineError("joint_values must map joint names to numbers, or name a group_state")
    return {k: float(v) for k, v in value.items()}
