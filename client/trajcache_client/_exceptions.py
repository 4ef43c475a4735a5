"""Exceptions raised by the client.

Our exception hierarchy:

* TrajcacheError
  x TransportError ........ no HTTP answer (connection refused, reset, DNS, protocol error)
    · TransportTimeoutError  the connect, read, write or pool timeout expired
  x UnexpectedResponseError  a success answer the client cannot read
  x APIError .............. the service answered with an error status
    · BadRequestError ....... 400
    · AuthError ............. 401, 403
    · NotFoundError ......... 404
    · ConflictError ......... 409
    · PayloadTooLargeError .. 413
    · UnsupportedMediaTypeError 415
    · ValidationError ....... 422 (`errors` lists the invalid fields when the service names them)
    · ServerError ........... 5xx
      · UnavailableError .... 503 (database or service unavailable; retried by default)
"""

from __future__ import annotations

from typing import Any

import httpx


class TrajcacheError(Exception):
    """Base class of every error the client raises."""


class TransportError(TrajcacheError):
    """The request got no HTTP answer."""

    def __init__(self, message: str, *, request: httpx.Request | None = None) -> None:
        super().__init__(message)
        self.request = request


class TransportTimeoutError(TransportError):
    """A connect, read, write or pool timeout expired."""


class UnexpectedResponseError(TrajcacheError):
    """A success answer whose body is not what the endpoint returns."""

    def __init__(self, message: str, *, response: httpx.Response) -> None:
        super().__init__(message)
        self.response = response


class APIError(TrajcacheError):
    """The service answered with an error status; `detail` is its message."""

    def __init__(self, detail: str, *, response: httpx.Response) -> None:
        request = response.request
        super().__init__(f"{response.status_code} {request.method} {request.url.path}: {detail}")
        self.detail = detail
        self.response = response

    @property
    def status_code(self) -> int:
        """The HTTP status of the answer."""
        return self.response.status_code


class BadRequestError(APIError):
    """400: the request could not be read."""


class AuthError(APIError):
    """401 or 403: a missing or wrong API key, or a key without the needed role."""


class NotFoundError(APIError):
    """404: an unknown robot, model or trajectory."""


class ConflictError(APIError):
    """409: the request conflicts with stored data (e.g. a robot of another model)."""


class PayloadTooLargeError(APIError):
    """413: a URDF, archive, scene or trajectory above the service's size limits."""


class UnsupportedMediaTypeError(APIError):
    """415: a body in a content type the endpoint does not accept."""


class ValidationError(APIError):
    """422: invalid input; `detail` names what is wrong, `errors` lists fields when known."""

    def __init__(
        self, detail: str, *, response: httpx.Response, errors: list[dict[str, Any]]
    ) -> None:
        super().__init__(detail, response=response)
        self.errors = errors


class ServerError(APIError):
    """5xx: the service failed to answer."""


class UnavailableError(ServerError):
    """503: the service or its database is unavailable for now."""


_BY_STATUS: dict[int, type[APIError]] = {
    400: BadRequestError,
    401: AuthError,
    403: AuthError,
    404: NotFoundError,
    409: ConflictError,
    413: PayloadTooLargeError,
    415: UnsupportedMediaTypeError,
    503: UnavailableError,
}


def _detail_of(response: httpx.Response) -> tuple[str, list[dict[str, Any]]]:
    try:
        body = response.json()
    except ValueError:
        text = response.text.strip()
        return (text[:500] or response.reason_phrase or "error"), []
    if not isinstance(body, dict):
        return str(body)[:500], []
    detail = body.get("detail", body)
    errors = body.get("errors")
    if isinstance(detail, list):  # FastAPI's default shape, from a proxy or an older service
        errors, detail = detail, "; ".join(str(e.get("msg", e)) for e in detail if e)
    listed = [e for e in errors if isinstance(e, dict)] if isinstance(errors, list) else []
    return str(detail), listed


def error_for(response: httpx.Response) -> APIError:
    """The exception for an error answer, chosen by its status."""
    detail, errors = _detail_of(response)
    status = response.status_code
    if status == 422:
        return ValidationError(detail, response=response, errors=errors)
    kind = _BY_STATUS.get(status, ServerError if status >= 500 else APIError)
    return kind(detail, response=response)
