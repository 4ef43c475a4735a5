"""The asyncio client (the twin of `Client`)."""

from __future__ import annotations

import asyncio
import ssl
from collections.abc import AsyncIterator, Iterable, Mapping
from types import TracebackType
from typing import Any, TypeVar

import httpx

from trajcache_client import _admin_operations as admin_ops
from trajcache_client._base import DEFAULT_BASE_URL, DEFAULT_RETRY, DEFAULT_TIMEOUT, BaseClient
from trajcache_client._endpoints import AsyncCaller, Endpoints
from trajcache_client._exceptions import error_for
from trajcache_client._operations import Operation
from trajcache_client._retry import Retry

T = TypeVar("T")


class AsyncClient(Endpoints, AsyncCaller, BaseClient):
    """An asyncio trajcache client; use it with `async with` or call `aclose()`.

    `transport` replaces the network (e.g. `httpx.MockTransport`, `httpx.ASGITransport(app)`).
    `verify` is httpx's (a TLS context, or False); by default every client shares one context.
    """

    def __init__(
        self,
        base_url: str = DEFAULT_BASE_URL,
        *,
        api_key: str | None = None,
        headers: Mapping[str, str] | None = None,
        timeout: float | httpx.Timeout | None = DEFAULT_TIMEOUT,
        retry: Retry = DEFAULT_RETRY,
        transport: httpx.AsyncBaseTransport | None = None,
        verify: ssl.SSLContext | bool | None = None,
    ) -> None:
        super().__init__(
            base_url, api_key=api_key, headers=headers, timeout=timeout, retry=retry, verify=verify
        )
        self._http = httpx.AsyncClient(transport=transport, **self._http_options())

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        """Close the connections."""
        await self._http.aclose()

    async def call(self, op: Operation[T]) -> T:
        """Send `op`, retrying as the policy allows, and return its answer or raise."""
        return self._result(op, await self._send(op))

    async def _send(self, op: Operation[Any], *, stream: bool = False) -> httpx.Response:
        """The answer to `op` once the retry policy lets it stand (streamed: still unread)."""
        retry = 0
        while True:
            try:
                response = await self._http.send(self._request(self._http, op), stream=stream)
            except httpx.TransportError as exc:
                wait = self._wait_after_error(op, retry, exc)
                if wait is None:
                    raise self._transport_error(op, exc) from exc
            else:
                wait = self._wait_after_answer(op, retry, response)
                if wait is None:
                    return response
                await response.aclose()
            await asyncio.sleep(wait)
            retry += 1

    async def iter_export_cache(
        self,
        *,
        model_ids: Iterable[str] = (),
        sources: Iterable[str] = (),
        newer_than_s: float | None = None,
        older_than_s: float | None = None,
        models: bool = True,
        chunk_size: int | None = None,
    ) -> AsyncIterator[bytes]:
        """The cache as JSON Lines, chunk by chunk as it arrives (sent on the first read)."""
        op = admin_ops.export_cache(
            model_ids=model_ids,
            sources=sources,
            newer_than_s=newer_than_s,
            older_than_s=older_than_s,
            models=models,
        )
        response = await self._send(op, stream=True)
        try:
            if not response.is_success:
                await response.aread()
                raise error_for(response)
            async for chunk in response.aiter_bytes(chunk_size):
                yield chunk
        except httpx.TransportError as exc:
            raise self._transport_error(op, exc) from exc
        finally:
            await response.aclose()
