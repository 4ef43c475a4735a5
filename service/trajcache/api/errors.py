"""Exception → HTTP response mapping; every error body is `{"detail": "<readable message>"}`."""

from __future__ import annotations

import logging
import uuid
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

from trajcache.api.refusals import recording_refusals
from trajcache.core.field_errors import readable_errors, validation_message
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
_MAX_LISTED_ERRORS = 10  # as many as validation_message lists
_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers on `app`."""
    # A plan route's 4xx to a caller the key check let through is a refusal (`api.refusals`).
    app.add_exception_handler(GeometryError, recording_refusals(_geometry_error))
    app.add_exception_handler(ServiceError, recording_refusals(_service_error))
    app.add_exception_handler(DBAPIError, _database_error)
    app.add_exception_handler(PoolTimeoutError, _pool_timeout)
    app.add_exception_handler(RequestValidationError, recording_refusals(_validation_error))
    app.add_exception_handler(HTTPException, recording_refusals(_http_error))
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


def _routed(request: Request, path: str) -> bool:
    """Whether some route or mount of the app takes `path` (with any method)."""
    probe = {k: request.scope[k] for k in ("type", "root_path") if k in request.scope}
    probe.update(path=path, method=request.method)
    return any(r.matches(probe)[0] is not Match.NONE for r in request.app.router.routes)


def _not_found(request: Request) -> JSONResponse:
    """A path no route takes: a 307 to the path without (or with) its trailing slash when a
    route takes that one, with a body naming it; else a 404 that names the path."""
    path = request.url.path
    other = path[:-1] if path.endswith("/") else f"{path}/"
    if other and path != "/" and _routed(request, other):
        location = f"{other}?{request.url.query}" if request.url.query else other
        message = f"{path} is served at {other}: send the request there"
        return JSONResponse({"detail": message}, status_code=307, headers={"Location": location})
    return _detail(404, f"no such path: {path}; the API's paths are listed at /docs")


async def _http_error(request: Request, exc: Exception) -> Response:
    # A 405 lists every method of the path: the router names only those of one of its routes.
    assert isinstance(exc, HTTPException)
    if exc.status_code == 404 and not _routed(request, request.url.path):
        return _not_found(request)
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


async def _validation_error(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    errors = readable_errors(exc.errors())
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
