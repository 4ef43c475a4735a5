"""Exception → HTTP response mapping; every error body is `{"detail": "<readable message>"}`."""

from __future__ import annotations

import logging
import uuid
from collections.abc import Sequence
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from sqlalchemy.exc import (
    DataError,
    DBAPIError,
    IntegrityError,
    InterfaceError,
    OperationalError,
)
from sqlalchemy.exc import TimeoutError as PoolTimeoutError
from starlette.exceptions import HTTPException
from starlette.routing import Match, Mount
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from trajcache.geometry.errors import GeometryError
from trajcache.services.errors import (
    DATABASE_UNAVAILABLE,
    AuthenticationError,
    ConflictError,
    InvalidInputError,
    NotFoundError,
    PayloadTooLargeError,
    PermissionDeniedError,
    ServiceError,
    UnavailableError,
)

logger = logging.getLogger(__name__)

_STATUS: tuple[tuple[type[Exception], int], ...] = (
    (AuthenticationError, 401),
    (PermissionDeniedError, 403),
    (NotFoundError, 404),
    (ConflictError, 409),
    (PayloadTooLargeError, 413),
    (InvalidInputError, 422),
    (UnavailableError, 503),
)
_MAX_LISTED_ERRORS = 10
_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers on `app`."""
    app.add_exception_handler(GeometryError, _geometry_error)
    app.add_exception_handler(ServiceError, _service_error)
    app.add_exception_handler(DBAPIError, _database_error)
    app.add_exception_handler(PoolTimeoutError, _pool_timeout)
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(HTTPException, _http_error)
    app.add_exception_handler(Exception, _unexpected_error)


def _detail(status: int, message: str, **extra: Any) -> JSONResponse:
    return JSONResponse(status_code=status, content={"detail": message, **extra})


def allowed_methods(request: Request) -> list[str]:
    """The methods some route of the app answers on the request's path."""
    routes = [r for r in request.app.router.routes if not isinstance(r, Mount)]
    probe = {k: request.scope[k] for k in ("type", "path", "root_path") if k in request.scope}
    return [
        method
        for method in _METHODS
        if any(r.matches({**probe, "method": method})[0] is Match.FULL for r in routes)
    ]


async def _http_error(request: Request, exc: Exception) -> Response:
    # A 405 lists every method of the path: the router names only those of one of its routes.
    assert isinstance(exc, HTTPException)
    if exc.status_code != 405 or not (allowed := allowed_methods(request)):
        return await http_exception_handler(request, exc)
    response = _detail(
        405,
        f"method {request.method} is not allowed on {request.url.path}; "
        f"allowed: {', '.join(allowed)}",
    )
    response.headers["Allow"] = ", ".join(allowed)
    return response


async def _geometry_error(_request: Request, exc: Exception) -> JSONResponse:
    return _detail(422, str(exc) or type(exc).__name__)


async def _service_error(_request: Request, exc: Exception) -> JSONResponse:
    status = next((code for kind, code in _STATUS if isinstance(exc, kind)), 500)
    if status == 500:
        logger.error("unmapped service error", exc_info=exc)
    response = _detail(status, str(exc) or type(exc).__name__)
    if status == 401:
        response.headers["WWW-Authenticate"] = "Bearer"
    return response


def _db_message(exc: DBAPIError) -> str:
    text = str(exc.orig if exc.orig is not None else exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


async def _database_error(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, DBAPIError)
    if isinstance(exc, IntegrityError):
        return _detail(409, f"conflicts with stored data: {_db_message(exc)}")
    if isinstance(exc, DataError):
        return _detail(422, f"value not accepted by the database: {_db_message(exc)}")
    if isinstance(exc, OperationalError | InterfaceError) or exc.connection_invalidated:
        logger.warning("database unavailable: %s", _db_message(exc))
        return _detail(503, DATABASE_UNAVAILABLE)
    logger.error("database error", exc_info=exc)
    return _detail(500, "internal database error")


async def _pool_timeout(_request: Request, exc: Exception) -> JSONResponse:
    logger.warning("database connection pool exhausted: %s", exc)
    return _detail(503, f"{DATABASE_UNAVAILABLE}: no free connection in the pool")


def _location(loc: Sequence[Any]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out


def validation_message(errors: Sequence[Any]) -> str:
    """One readable line naming each invalid field, e.g. `body.states[0][1]: ...`."""
    parts = []
    for error in errors[:_MAX_LISTED_ERRORS]:
        where = _location(error.get("loc", ()))
        message = str(error.get("msg", "invalid value"))
        reason = (error.get("ctx") or {}).get("error")
        if error.get("type") == "json_invalid" and reason:
            message = f"{message} ({reason})"
        parts.append(f"{where}: {message}" if where else message)
    if len(errors) > _MAX_LISTED_ERRORS:
        parts.append(f"and {len(errors) - _MAX_LISTED_ERRORS} more error(s)")
    return "; ".join(parts) or "invalid request"


async def _validation_error(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    errors = list(exc.errors())
    listed = [
        {"loc": list(e.get("loc", ())), "msg": str(e.get("msg", "")), "type": str(e.get("type"))}
        for e in errors[:_MAX_LISTED_ERRORS]
    ]
    return _detail(422, validation_message(errors), errors=listed)


async def _unexpected_error(request: Request, exc: Exception) -> JSONResponse:
    return _internal_error(request.method, request.url.path, exc)


def _internal_error(method: str, path: str, exc: BaseException) -> JSONResponse:
    error_id = uuid.uuid4().hex[:12]
    logger.error("unhandled error %s in %s %s", error_id, method, path, exc_info=exc)
    return _detail(500, f"internal server error (error id {error_id})", error_id=error_id)


class UnexpectedErrorMiddleware:
    """Answers an exception no handler took with a 500 that carries an error id (also logged
    with the traceback), instead of letting it reach the server: the server would then close
    the keep-alive connection, and the client's next request on it would get no answer. An
    exception after the response has started cannot be answered and is raised as before."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = False

        async def tracked(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, receive, tracked)
        except Exception as exc:
            if started:
                raise
            response = _internal_error(scope.get("method", ""), scope.get("path", ""), exc)
            await response(scope, receive, send)
