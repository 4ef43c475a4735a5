"""Plan requests refused before an answer, recorded as plan events with status `refused`.

A refusal is a plan request the service would not answer: a 4xx of a plan route (a goal in
collision, an unknown robot, a malformed body, no scene under `require_scene`), or the MoveIt
route's in-band refusal of the same mistakes. Its event keeps the reason (the answer's message,
cut to the column's 500 characters), never the request body, and no timing but the total: a
refusal is counted apart from the answered requests (`services.stats.window`). It goes to
the record writer like every plan event, so it is written in order, off the request path, and
is counted in the Prometheus metrics (`metrics.record_refusal`).

Only callers the service let through leave one: the HTTP layer records a refusal only after the
request passed the API-key check (`api.auth`), so an unauthenticated caller (401), a key without
the right (403), or a body refused before the caller is known (413, unreadable JSON) writes
nothing. Nor does a request whose robot id is not a robot id at all (too long, other characters):
its refusal names no robot it could be counted for, so only the Prometheus counter sees it.
"""

from __future__ import annotations

import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from trajcache.db.models import Robot
from trajcache.services.bookkeeping.metrics import record_refusal as count_refusal
from trajcache.services.bookkeeping.outcomes import Requester
from trajcache.services.bookkeeping.records import PlanRecord, PlanRecorder
from trajcache.services.catalog.robots import check_robot_id
from trajcache.services.errors import InvalidInputError

__all__ = ["REFUSED", "record_refusal"]

REFUSED = "refused"
_REASON_CHARS = 500  # plan_events.error


def record_refusal(
    *,
    sessions: sessionmaker[Session],
    records: PlanRecorder,
    robot_id: str,
    reason: str,
    total_ms: float,
) -> int | None:
    """Queue the plan event of a refused request of robot `robot_id`; its record's number (None:
    no event, for an id that cannot name a robot).

    The event names the robot's model when the robot exists ("" for an unknown robot)."""
    count_refusal(requester=Requester.ROBOT.value)
    try:
        check_robot_id(robot_id)
    except InvalidInputError:
        return None
    with sessions() as session:
        model_id = session.scalar(sa.select(Robot.model_id).where(Robot.id == robot_id))
    event = {
        "robot_id": robot_id,
        "requester": Requester.ROBOT.value,
        "model_id": model_id or "",
        "status": REFUSED,
        "candidates_tried": 0,
        "lookup_ms": 0.0,
        "validate_ms": 0.0,
        "plan_ms": 0.0,
        "total_ms": round(total_ms, 3),
        "error": _reason(reason),
    }
    return records.submit(PlanRecord(records.now(), None, (), event))


def _reason(text: str) -> str:
    text = text.strip() or "refused"
    return text if len(text) <= _REASON_CHARS else f"{text[: _REASON_CHARS - 1]}…"
