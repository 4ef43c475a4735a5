"""Importing an export into a database, in one transaction (the format: `transfer`).

Every line is checked on its own: a JSON object that fails its checks is rejected with its
number and reason and the rest is imported. A line that is not JSON (a corrupt or cut file), a
header of another format or a newer version, or a version-2 export without its end line (cut
short) refuses the whole import: nothing is stored. Trajectories are written in batches
(`bulk_insert`), all inside the one transaction. Their quality (timing, clearance) is not
computed here: new rows are marked pending and the service computes it in the background
(`backfill`). Their end poses are indexed with each batch (`end_poses`), in the transaction.
Cartesian paths (version 3) are checked as data and written in batches too
(`cartesian_transfer`); they are proven, in the robot's scene, before they serve. Models
registered by the import reach the process's registry only once it is committed.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

import numpy as np
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from trajcache.core.config import Settings
from trajcache.geometry.errors import GeometryError
from trajcache.geometry.model.robot import RobotModel
from trajcache.services.catalog.end_poses import write_end_poses
from trajcache.services.catalog.models import (
    ModelRegistration,
    ModelRegistry,
    get_model,
    register_model,
)
from trajcache.services.catalog.trajectories import SOURCES, new_row_values
from trajcache.services.errors import (
    ConflictError,
    InvalidInputError,
    NotFoundError,
    ServiceError,
)
from trajcache.services.maintenance.bulk_insert import DEFAULT_BATCH_ROWS, BatchWriter
from trajcache.services.maintenance.cartesian_transfer import (
    CartesianLineError,
    CartesianWriter,
    cartesian_values,
)
from trajcache.services.maintenance.transfer import COUNTERS, FORMAT, FORMAT_VERSION, TIMES

MAX_LISTED_REJECTS = 1000


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
    cartesian_inserted: int = 0
    cartesian_duplicates: int = 0
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
        batch_rows: int = DEFAULT_BATCH_ROWS,
    ) -> None:
        if source is not None and source not in SOURCES:
            raise InvalidInputError(f"source {source!r} must be one of {', '.join(SOURCES)}")
        self.session = session
        self.registry = registry
        self.settings = settings
        self.source = source
        self.report = ImportReport()
        self._model_ids: dict[str, str] = {}  # id in the file -> id in this database
        self._models: dict[str, RobotModel] = {}
        self._writer = BatchWriter(session, batch_rows=batch_rows, inserted_fn=self._index_ends)
        self._paths = CartesianWriter(session, batch_rows=batch_rows)
        self._version = 0  # of the header; 0: no header read
        self._ended = False

    def feed(self, line_no: int, text: str) -> None:
        """Import one line (blank lines are skipped)."""
        if not text.strip():
            return
        self.report.lines += 1
        if self._ended:
            raise ImportFormatError(f"line {line_no}: text after the export's end line")
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
            elif kind == "cartesian_path":
                model = self._model_for(record.get("model_id"))
                self._paths.add(cartesian_values(model, record))
            elif kind == "end":
                self._ended = True  # version 2: the export was written to its end
            else:
                raise _LineError(f"unknown line type {kind!r:.40}")
        except json.JSONDecodeError as exc:
            raise ImportFormatError(
                f"line {line_no}: not JSON: {exc.msg} (column {exc.colno})"
            ) from None
        except RecursionError:
            self.report.reject(line_no, "not valid JSON: it nests too deeply")
        except ImportFormatError:
            raise
        except (_LineError, CartesianLineError, GeometryError, ServiceError) as exc:
            self.report.reject(line_no, str(exc)[:500])

    def finish(self) -> ImportReport:
        """Write the last batch, commit the import and return the report."""
        if self._version >= 2 and not self._ended:
            raise ImportFormatError(
                "the export ends without its end line: it was cut short; nothing was imported"
            )
        self._paths.flush()
        self._writer.finish()  # its last batch, then the commit-log rows, just before the commit
        self.report.inserted += self._writer.inserted
        self.report.duplicates += self._writer.duplicates
        self.report.cartesian_inserted += self._paths.inserted
        self.report.cartesian_duplicates += self._paths.duplicates
        self.session.commit()
        for model in self._models.values():
            self.registry.put(model)
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
        self._version = version

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
        model, created = register_model(
            session=self.session,
            registry=ModelRegistry(),  # the real one once committed (`finish`)
            max_urdf_bytes=self.settings.max_urdf_bytes,
            commit=False,
            registration=ModelRegistration(
                urdf=urdf,
                files=files,
                base=str(record.get("base", "fixed")),
                joint_names=record.get("joint_names"),
                srdf=_optional_text(record.get("srdf"), "srdf"),
                joint_values=_joint_values(record.get("joint_values")),
                name=record.get("name"),
                acceleration_limits=record.get("acceleration_limits"),
                jerk_limits=record.get("jerk_limits"),
                end_effector_link=record.get("end_effector_link"),
            ),
        )
        if created:
            self.report.models_created += 1
        else:
            self.report.models_existing += 1
        self._model_ids[file_id] = model.model_id
        self._models[model.model_id] = model

    def _model_for(self, file_id: Any) -> RobotModel:
        if not isinstance(file_id, str) or not file_id:
            raise _LineError("a trajectory or Cartesian path line needs a model_id")
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

    def _index_ends(self, session: Session, rows: list[dict[str, Any]]) -> None:
        """Write the end poses of the rows a batch inserted, model by model."""
        for model_id in {row["model_id"] for row in rows}:
            mine = [row for row in rows if row["model_id"] == model_id]
            starts = np.array([row["start"] for row in mine], dtype=float)
            goals = np.array([row["goal"] for row in mine], dtype=float)
            ids = [row["id"] for row in mine]
            write_end_poses(session, self._models[model_id], ids, starts, goals)

    def _trajectory(self, record: Mapping[str, Any]) -> None:
        model = self._model_for(record.get("model_id"))
        values = new_row_values(
            model,
            _states(record),
            source=self.source or _optional_str(record, "source") or "import",
            robot_id=_optional_str(record, "robot_id"),
            scene_hash=_optional_str(record, "scene_hash"),
            env=_env(record),
            planning_time_ms=_optional_number(record, "planning_time_ms"),
            max_states=self.settings.max_trajectory_states,
        )
        expected = record.get("content_hash")
        if expected is not None and expected != values["content_hash"]:
            raise _LineError("content_hash does not match the states")
        values.update({name: _counter(record, name) for name in COUNTERS})
        values.update({name: _timestamp(record, name) for name in TIMES})
        values["created_at"] = values["created_at"] or datetime.now(UTC)
        values["quality_pending"] = True  # computed by the service in the background
        self._writer.add(values)


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
    batch_rows: int = DEFAULT_BATCH_ROWS,
) -> ImportReport:
    """Import export lines in one transaction; the report lists the rejected ones."""
    importer = Importer(
        session=session, registry=registry, settings=settings, source=source, batch_rows=batch_rows
    )
    try:
        for number, text in enumerate(lines, start=1):
            importer.feed(number, text)
        return importer.finish()
    except IntegrityError:  # another writer stored the same model meanwhile
        session.rollback()
        raise ConflictError(
            "a model or trajectory of this import was stored concurrently; nothing was "
            "imported, retry"
        ) from None
    except BaseException:
        session.rollback()
        raise


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
