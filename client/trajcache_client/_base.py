"""What `Client` and `AsyncClient` share: configuration, request building, retry decisions."""

from __future__ import annotations

import functools
import logging
import ssl
from collections.abc import Mapping
from typing import Any, TypeVar

import httpx

from trajcache_client._exceptions import TransportError, TransportTimeoutError, error_for
from trajcache_client._operations import Operation
from trajcache_client._retry import NO_RETRY, Retry
from trajcache_client._version import __version__

T = TypeVar("T")

DEFAULT_BASE_URL = "http://127.0.0.1:8000"
DEFAULT_TIMEOUT = httpx.Timeout(30.0, connect=5.0)
DEFAULT_RETRY = Retry()

logger = logging.getLogger("trajcache_client")


@functools.cache
def default_tls() -> ssl.SSLContext:
    """httpx's default TLS context (certifi's CA bundle, or SSL_CERT_FILE / SSL_CERT_DIR), built
    once per process. httpx builds one per client, and loading the CA bundle costs 40-200 ms:
    more than a short-lived client's calls (a readiness poll, a CLI command)."""
    return httpx.create_ssl_context()


class BaseClient:
    """Settings of a client and the parts of a call that do not depend on sync or async I/O."""

    def __init__(
        self,
        base_url: str,
        *,
        api_key: str | None,
        headers: Mapping[str, str] | None,
        timeout: float | httpx.Timeout | None,
        retry: Retry,
        verify: ssl.SSLContext | bool | None = None,
    ) -> None:
        self.base_url = base_url.rstrip("/")
        self.verify = default_tls() if verify is None or verify is True else verify
        self.retry = retry
        self.timeout = httpx.Timeout(timeout)
        merged = {"user-agent": f"trajcache-client/{__version__}", "accept": "application/json"}
        if api_key is not None:
            merged["authorization"] = f"Bearer {api_key}"
        merged.update(headers or {})
        self.headers = merged

    def _http_options(self) -> dict[str, Any]:
        return {
            "base_url": self.base_url,
            "headers": self.headers,
            "timeout": self.timeout,
            "verify": self.verify,
        }

    def _timeout_for(self, op: Operation[Any]) -> httpx.Timeout:
        read = self.timeout.read
        if op.read_timeout_s is None or read is None or read >= op.read_timeout_s:
            return self.timeout
        return httpx.Timeout(
            connect=self.timeout.connect,
            read=op.read_timeout_s,
            write=self.timeout.write,
            pool=self.timeout.pool,
        )

    def _request(self, http: httpx.Client | httpx.AsyncClient, op: Operation[Any]) -> httpx.Request:
        return http.build_request(
            op.method,
            op.path,
            params=op.params,
            json=op.json,
            content=op.content,
            data=op.data,
            files=op.files,
            headers=op.headers,
            timeout=self._timeout_for(op),
        )

    def _wait_after_error(
        self, op: Operation[Any], retry: int, error: httpx.TransportError
    ) -> float | None:
        """Seconds to wait before trying again after `error`, or None to give up."""
        policy = self.retry if op.retry else NO_RETRY
        if retry >= policy.retries or not policy.retry_error(error, idempotent=op.idempotent):
            return None
        wait = policy.delay(retry)
        logger.warning("%s %s failed (%s); retry in %.2f s", op.method, op.path, error, wait)
        return wait

    def _wait_after_answer(
        self, op: Operation[Any], retry: int, response: httpx.Response
    ) -> float | None:
        """Seconds to wait before trying again after an error answer, or None to give up."""
        policy = self.retry if op.retry else NO_RETRY
        if response.is_success or retry >= policy.retries:
            return None
        if not policy.retry_status(response.status_code, idempotent=op.idempotent):
            return None
        wait = policy.delay(retry, response)
        logger.warning(
            "%s %s answered %d; retry in %.2f s", op.method, op.path, response.status_code, wait
        )
        return wait

    @staticmethod
    def _result(op: Operation[T], response: httpx.Response) -> T:
        if not response.is_success:
            raise error_for(response)
        return op.read(response)

    @staticmethod
    def _transport_error(op: Operation[Any], error: httpx.TransportError) -> TransportError:
        timed_out = isinstance(error, httpx.TimeoutException)
        kind = TransportTimeoutError if timed_out else TransportError
        message = f"{op.method} {op.path}: {type(error).__name__}: {error}"
        try:
            request: httpx.Request | None = error.request
        except RuntimeError:  # raised by httpx when the error has no request attached
            request = None
        return kind(message, request=request)
