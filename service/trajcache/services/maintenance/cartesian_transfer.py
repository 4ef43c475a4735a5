"""Cartesian paths in an export (format version 3): their lines, written and read.

A line is `{"type": "cartesian_path", "model_id", "link", "params", "waypoints": [[x, y, z,
qx, qy, qz, qw], ...], "start": [...], "states": [[...], ...], "line_of": [...]}`, after the
trajectories, each path after its model's line. Only the request a path answered and its states
travel: nothing that vouches for them. Import checks each line as data (the model knows the
link; states of the model's length, finite and within its joint limits, the first the start;
unit quaternions; one line index a state, in order) and stores it; whether the states follow the
lines within the request's tolerances, and whether the motion is free in the robot's current
scene, is proven when a request would be served the path (`services.cartesian.store`), as for a
path computed here. A path is identified by its model, link, parameters, start, waypoints and
states: importing it twice stores one row. Rows are written in batches inside the importer's
transaction.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db.cartesian import CartesianPathRow
from trajcache.geometry.model.kinematics import check_limits, check_states
from trajcache.geometry.model.robot import RobotModel

_C = CartesianPathRow
MAX_STATES = (
    2001  # a path of at most MAX_SAMPLES samples (`services.cartesian.path`), and its start
)
_DIGEST_CHARS = frozenset("0123456789abcdef")


class CartesianLineError(ValueError):
    """A Cartesian path line that cannot be imported (the message says why)."""


def cartesian_records(session: Session, model_ids: tuple[str, ...]) -> Iterator[dict[str, Any]]:
    """The stored paths (of `model_ids`; all when empty) by model, then id, as export lines."""
    statement = sa.select(_C).order_by(_C.model_id, _C.id).execution_options(yield_per=500)
    if model_ids:
        statement = statement.where(_C.model_id.in_(model_ids))
    for row in session.scalars(statement):
        yield {
            "type": "cartesian_path",
            "model_id": row.model_id,
            "link": row.link,
            "params": row.params,
            "waypoints": row.waypoints,
            "start": row.start,
            "states": row.states,
            "line_of": row.line_of,
        }


def cartesian_values(model: RobotModel, record: Mapping[str, Any]) -> dict[str, Any]:
    """The row of a Cartesian path line, checked as data (module docstring)."""
    link = record.get("link")
    if not isinstance(link, str) or link not in model.link_names:
        raise CartesianLineError(f"link {link!r:.80} is not a link of model {model.model_id}")
    params = record.get("params")
    if not isinstance(params, str) or len(params) != 64 or not _DIGEST_CHARS.issuperset(params):
        raise CartesianLineError("params must be the 64 hex digits of a parameter digest")
    waypoints = _waypoints(record.get("waypoints"))
    states = record.get("states")
    if not isinstance(states, list) or not 2 <= len(states) <= MAX_STATES:
        raise CartesianLineError(f"states must be a list of 2 to {MAX_STATES} states")
    if not isinstance(record.get("start"), list):
        raise CartesianLineError("start must be a list of numbers")
    start = check_states(model, record["start"], name="start")[0]
    path = check_states(model, states, name="states")
    check_limits(model, path, name="states")
    if not np.array_equal(path[0], start):
        raise CartesianLineError("the first state must be the start")
    line_of = _line_of(record.get("line_of"), len(states), len(waypoints))
    return {
        "model_id": model.model_id,
        "link": link,
        "params": params,
        "waypoints": waypoints,
        "start": start.tolist(),
        "states": path.tolist(),
        "line_of": line_of,
    }


def _waypoints(value: Any) -> list[list[float]]:
    if not isinstance(value, list) or not value:
        raise CartesianLineError("waypoints must be a non-empty list")
    out = []
    for k, waypoint in enumerate(value):
        if (
            not isinstance(waypoint, list)
            or len(waypoint) != 7
            or not all(_finite(v) for v in waypoint)
        ):
            raise CartesianLineError(
                f"waypoints[{k}] must be 7 finite numbers: x, y, z, quaternion"
            )
        if abs(math.hypot(*waypoint[3:]) - 1.0) > 1e-6:
            raise CartesianLineError(f"waypoints[{k}]: the quaternion is not a unit one")
        out.append([float(v) for v in waypoint])
    return out


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _line_of(value: Any, states: int, waypoints: int) -> list[int]:
    if (
        not isinstance(value, list)
        or len(value) != states
        or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)
    ):
        raise CartesianLineError("line_of must be one integer a state")
    if value[0] != 0 or any(b < a for a, b in itertools.pairwise(value)):
        raise CartesianLineError("line_of must start at 0 and never decrease")
    if value[-1] >= waypoints:
        raise CartesianLineError(f"line_of names line {value[-1]} of {waypoints}")
    return list(value)


def path_key(values: Mapping[str, Any]) -> str:
    """What identifies a stored path (module docstring)."""
    fields = [values[k] for k in ("model_id", "link", "params", "start", "waypoints", "states")]
    return hashlib.sha256(json.dumps(fields).encode()).hexdigest()


class CartesianWriter:
    """Collects imported paths (`add`) and inserts the new ones a batch at a time (`flush`)."""

    def __init__(self, session: Session, *, batch_rows: int) -> None:
        self.session = session
        self.batch_rows = max(1, batch_rows)
        self.inserted = 0
        self.duplicates = 0
        self._pending: list[dict[str, Any]] = []
        self._known: dict[tuple[str, str, str], set[str]] = {}

    def add(self, values: Mapping[str, Any]) -> None:
        """Queue one path unless it is stored already (or queued)."""
        keys = self._keys((values["model_id"], values["link"], values["params"]))
        key = path_key(values)
        if key in keys:
            self.duplicates += 1
            return
        keys.add(key)
        self._pending.append(dict(values))
        if len(self._pending) >= self.batch_rows:
            self.flush()

    def flush(self) -> None:
        """Insert the queued paths (inside the session's transaction)."""
        if self._pending:
            self.session.execute(sa.insert(_C), self._pending)
            self.inserted += len(self._pending)
            self._pending = []

    def _keys(self, group: tuple[str, str, str]) -> set[str]:
        """The keys of the stored paths of one model, link and parameter digest."""
        if group not in self._known:
            model_id, link, params = group
            rows = self.session.execute(
                sa.select(_C.model_id, _C.link, _C.params, _C.start, _C.waypoints, _C.states).where(
                    _C.model_id == model_id, _C.link == link, _C.params == params
                )
            )
            self._known[group] = {path_key(dict(row._mapping)) for row in rows}
        return self._known[group]
