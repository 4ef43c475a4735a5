"""Routes whose request bodies are bounded by `max_body_bytes` while they are read.

`APIRouter(route_class=BoundedBodyRoute)`: the body is read chunk by chunk and refused (413) as
soon as it passes the limit, before JSON parsing, so a huge body never sits in memory whole.
"""

from __future__ import annotations

from collections.abc import Callable, Coroutine
from typing import Any

from fastapi import Request, Response
from fastapi.routing import APIRoute
from starlette.exceptions import HTTPException


class BoundedRequest(Request):
    """A request whose `body()` stops reading past the app's `max_body_bytes`."""

    async def body(self) -> bytes:
        """The body, or a 413 once it exceeds the limit."""
        if not hasattr(self, "_body"):
            limit = int(self.app.state.ctx.settings.max_body_bytes)
            declared = self.headers.get("content-length", "")
            if declared.isdigit() and int(declared) > limit:
                raise _too_large(_message(int(declared), limit))
            chunks: list[bytes] = []
            size = 0
            async for chunk in self.stream():
                size += len(chunk)
                if size > limit:
                    raise _too_large(_message(size, limit, at_least=True))
                chunks.append(chunk)
            self._body = b"".join(chunks)
        return self._body


def _too_large(message: str) -> HTTPException:
    # An HTTPException: FastAPI turns any other error while reading the body into a 400.
    return HTTPException(413, message)


def _message(size: int, limit: int, *, at_least: bool = False) -> str:
    amount = f"more than {limit}" if at_least else str(size)
    return f"request body has {amount} bytes, more than max_body_bytes={limit}"


class BoundedBodyRoute(APIRoute):
    """An APIRoute that reads its body through BoundedRequest."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        """The default handler, given a BoundedRequest."""
        handler = super().get_route_handler()

        async def bounded(request: Request) -> Response:
            return await handler(BoundedRequest(request.scope, request.receive))

        return bounded
