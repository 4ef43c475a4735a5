"""Routes whose request bodies are bounded by `max_body_bytes` while they are read.

`APIRouter(route_class=BoundedBodyRoute)`: the body is read chunk by chunk and refused (413) as
soon as it passes the limit, before JSON or form parsing, so a huge body never sits in memory (or
in a spooled upload file) whole. A JSON body that is not UTF-8 text, or nests too deeply, is a 422
like any other invalid JSON.

A route whose body is a JSON model reads it as JSON when the request names a JSON media type
(`application/json`, `application/*+json`) or none at all; any other type is a 415 naming it,
before the body is read.
"""

from __future__ import annotations

import json
from collections.abc import AsyncGenerator, Callable, Coroutine
from typing import Any

from fastapi import Request, Response, params
from fastapi.routing import APIRoute
from starlette.exceptions import HTTPException

from trajcache.api.responses import errors
from trajcache.core.config import Settings

BodyLimitFn = Callable[[Settings], tuple[int, str]]


def max_body_limit(settings: Settings) -> tuple[int, str]:
    """The limit of most routes: `max_body_bytes`."""
    return settings.max_body_bytes, f"max_body_bytes={settings.max_body_bytes}"


class BoundedRequest(Request):
    """A request whose body stream stops past its route's limit (`max_body_bytes` by default)."""

    limit_fn: BodyLimitFn = staticmethod(max_body_limit)

    async def stream(self) -> AsyncGenerator[bytes, None]:
        """The body's chunks, or a 413 once they exceed the limit."""
        if hasattr(self, "_body"):
            async for chunk in super().stream():
                yield chunk
            return
        limit, name = self.limit_fn(self.app.state.ctx.settings)
        declared = self.headers.get("content-length", "")
        if declared.isdigit() and int(declared) > limit:
            raise _too_large(f"request body has {int(declared)} bytes, more than {name}")
        size = 0
        async for chunk in super().stream():
            size += len(chunk)
            if size > limit:
                raise _too_large(f"request body has more than {limit} bytes, more than {name}")
            yield chunk

    async def json(self) -> Any:
        """The body as JSON; undecodable text is a JSONDecodeError (a 422), not a 400."""
        if not hasattr(self, "_json"):
            body = await self.body()
            try:
                text = body.decode("utf-8-sig")
            except UnicodeDecodeError as exc:
                raise json.JSONDecodeError("the body is not UTF-8 text", "", exc.start) from None
            try:
                self._json = json.loads(text)
            except RecursionError:
                raise json.JSONDecodeError("the JSON nests too deeply", text, 0) from None
        return self._json


def media_type(request: Request) -> str:
    """The request's media type, lower case and without parameters ("" when it names none)."""
    return request.headers.get("content-type", "").split(";")[0].strip().lower()


def is_json_media(media: str) -> bool:
    """Whether a body of media type `media` (see `media_type`) is read as JSON."""
    return media in ("", "application/json") or (
        media.startswith("application/") and media.endswith("+json")
    )


def unsupported_media(media: str, accepted: str) -> HTTPException:
    """The 415 of a body in media type `media`; `accepted` says what to send instead."""
    return HTTPException(415, f"unsupported content type {media!r}; send {accepted}")


NOT_JSON = errors(
    {
        415: (
            "The body is not JSON",
            "unsupported content type 'text/csv'; send application/json",
        )
    }
)


def _too_large(message: str) -> HTTPException:
    # An HTTPException: FastAPI turns any other error while reading the body into a 400.
    return HTTPException(413, message)


class BoundedBodyRoute(APIRoute):
    """An APIRoute that reads its body through BoundedRequest; a JSON model body only as JSON."""

    limit_fn: BodyLimitFn = staticmethod(max_body_limit)

    def __init__(self, path: str, endpoint: Callable[..., Any], **kwargs: Any) -> None:
        # Not strict: a JSON model body without a Content-Type header is read as JSON.
        super().__init__(path, endpoint, **{**kwargs, "strict_content_type": False})
        if self.reads_json_model:  # declared before the router's copy of the route is made
            self.responses = {**NOT_JSON, **self.responses}

    @property
    def reads_json_model(self) -> bool:
        """Whether FastAPI reads the body into a model (rather than the route reading it)."""
        field = self.body_field
        return field is not None and not isinstance(field.field_info, params.Form)

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        """The default handler, given a BoundedRequest; a 415 first for a body that is not JSON."""
        handler = super().get_route_handler()
        limit_fn = self.limit_fn
        json_only = self.reads_json_model

        async def bounded(request: Request) -> Response:
            if json_only and not is_json_media(media := media_type(request)):
                raise unsupported_media(media, "application/json")
            bounded_request = BoundedRequest(request.scope, request.receive)
            bounded_request.limit_fn = limit_fn
            return await handler(bounded_request)

        return bounded
