"""When a failed call is tried again, and how long the client waits before it does."""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from datetime import UTC, datetime
from email.utils import parsedate_to_datetime

import httpx

# The request never reached the service, so even a non-idempotent call can be sent again.
_NOT_SENT = (httpx.ConnectError, httpx.ConnectTimeout, httpx.PoolTimeout)
# Mistakes on this side (a bad URL scheme, a malformed request): trying again cannot help.
_PERMANENT = (httpx.UnsupportedProtocol, httpx.LocalProtocolError)


@dataclass(frozen=True)
class Retry:
    """Retry policy: `retries` further tries with exponential backoff.

    Idempotent calls (reads, PUT, DELETE, and the content-addressed POSTs) are retried on
    transport errors and on the `statuses`; other calls (plan, scene patch) only on 503 and on
    errors that prove the request was never sent. The n-th wait is
    `min(backoff_max_s, backoff_s * 2**n)`, less up to `jitter` of it at random, or what the
    service's `Retry-After` asks for when that is longer (still capped by `backoff_max_s`).
    """

    retries: int = 3
    backoff_s: float = 0.25
    backoff_max_s: float = 8.0
    jitter: float = 0.5
    statuses: frozenset[int] = field(default_factory=lambda: frozenset({502, 503, 504}))

    def __post_init__(self) -> None:
        if self.retries < 0:
            raise ValueError("retries must be >= 0")
        if self.backoff_s < 0 or self.backoff_max_s < 0:
            raise ValueError("backoff_s and backoff_max_s must be >= 0")
        if not 0 <= self.jitter <= 1:
            raise ValueError("jitter must be within [0, 1]")

    def retry_status(self, status: int, *, idempotent: bool) -> bool:
        """Whether an answer with this status may be tried again."""
        return status in self.statuses and (idempotent or status == 503)

    def retry_error(self, error: httpx.TransportError, *, idempotent: bool) -> bool:
        """Whether a call that failed with this transport error may be tried again."""
        if isinstance(error, _PERMANENT):
            return False
        return idempotent or isinstance(error, _NOT_SENT)

    def delay(self, retry: int, response: httpx.Response | None = None) -> float:
        """Seconds to wait before retry number `retry` (0-based)."""
        base = min(self.backoff_max_s, self.backoff_s * 2.0**retry)
        wait = base * (1.0 - self.jitter * random.random())
        asked = _retry_after(response) if response is not None else None
        if asked is not None:
            wait = max(wait, min(asked, self.backoff_max_s))
        return wait


NO_RETRY = Retry(retries=0)


def _retry_after(response: httpx.Response) -> float | None:
    value = response.headers.get("retry-after", "").strip()
    if not value:
        return None
    try:
        return max(0.0, float(value))
    except ValueError:
        pass
    try:
        when = parsedate_to_datetime(value)
    except (TypeError, ValueError):
        return None
    if when.tzinfo is None:
        when = when.replace(tzinfo=UTC)
    return max(0.0, (when - datetime.now(UTC)).total_seconds())
