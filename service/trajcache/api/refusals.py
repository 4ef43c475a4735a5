"""Refused plan requests leave a plan event (`services.bookkeeping.refusals`): the 4xx answers
of the plan routes, once the caller passed the API-key check.

`authorize` (`api.auth`) marks the request when it lets the caller through; an error answer of
a plan route to a marked request records the refusal with the answer's message as its reason.
A 401 or 403 is never recorded (the check refused the caller), nor is a body refused before
the check ran (413, a body that is not JSON). The MoveIt route answers its own refusals in-band
(200 with an error code) and records them itself.
"""

from __future__ import annotations

import json
import time
from collections.abc import Awaitable, Callable

from fastapi import Request
from starlette.background import BackgroundTask
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from trajcache.services.bookkeeping.refusals import record_refusal
from trajcache.services.context import ServiceContext

__all__ = ["PLAN_ROUTES", "mark_authorized", "record", "recording_refusals"]

# The endpoints (route names) whose error answers are refusals.
PLAN_ROUTES = frozenset({"plan_route", "motion_plan_route"})
_NOT_REFUSALS = (401, 403)  # the caller, not the plan, was refused

Handler = Callable[[Request, Exception], Awaitable[Response]]


def mark_authorized(request: Request) -> None:
    """Note that the API-key check let this request through (and when)."""
    request.state.authorized_at = time.perf_counter()


def _elapsed_ms(request: Request) -> float | None:
    """Milliseconds since the caller was let through; None if it was not (yet)."""
    began = getattr(request.state, "authorized_at", None)
    return None if began is None else (time.perf_counter() - began) * 1e3


def record(ctx: ServiceContext, request: Request, reason: str) -> BackgroundTask | None:
    """Record a refusal of a plan route for the request's robot (blocking: it reads the robot);
    the task that waits for its record, or None when the caller was not let through."""
    elapsed = _elapsed_ms(request)
    robot_id = request.path_params.get("robot_id")
    if elapsed is None or not isinstance(robot_id, str):
        return None
    seq = record_refusal(
        sessions=ctx.sessions,
        records=ctx.records,
        robot_id=robot_id,
        reason=reason,
        total_ms=elapsed,
    )
    # the cycle ends once it is written
    return None if seq is None else BackgroundTask(ctx.records.written, seq)


def recording_refusals(handler: Handler) -> Handler:
    """`handler`, recording the 4xx answers it gives a plan route as refusals."""

    async def handle(request: Request, exc: Exception) -> Response:
        response = await handler(request, exc)
        route = request.scope.get("route")
        status = response.status_code
        ctx: ServiceContext | None = getattr(request.app.state, "ctx", None)
        if (
            ctx is not None
            and getattr(route, "name", None) in PLAN_ROUTES
            and 400 <= status < 500
            and status not in _NOT_REFUSALS
        ):
            reason = _reason(response)
            response.background = await run_in_threadpool(record, ctx, request, reason)
        return response

    return handle


def _reason(response: Response) -> str:
    """The message of an error answer (`{"detail": ...}`)."""
    try:
        detail = json.loads(bytes(response.body)).get("detail")
    except (ValueError, AttributeError):
        detail = None
    return f"{response.status_code}: {detail if isinstance(detail, str) else 'refused'}"
