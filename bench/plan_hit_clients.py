"""bench/plan_hit.py's clients: one request at a time, timed, with the server's own breakdown.

Two client libraries on keep-alive connections: the lean one (the standard library's
http.client) and the Python client package (trajcache_client over httpx). Each answer keeps its
`timings_ms` and its `Server-Timing` header.
"""

from __future__ import annotations

import http.client
import json
import statistics
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import httpx

from trajcache_client import NO_RETRY, APIError, Client

CONCURRENCY = 16


@dataclass(frozen=True)
class Query:
    """One plan request of the workload, addressed to the robot that holds its scene."""

    robot_id: str
    body: dict[str, object]


PLAN_PARTS = {"db", "lookup", "validate", "plan", "total"}  # timings_ms inside the plan flow


@dataclass
class Sample:
    """What one request returned."""

    latency_ms: float
    hit: bool
    timings: dict[str, float] = field(default_factory=dict)  # timings_ms of the answer
    server_timing: dict[str, float] = field(default_factory=dict)  # the Server-Timing header

    @property
    def serialize_ms(self) -> float:
        """Time spent serializing the answer."""
        return self.server_timing.get("serialize", 0.0)

    @property
    def extras_ms(self) -> float:
        """Time the route spent besides the plan flow and serializing (answer extras)."""
        return sum(v for k, v in self.server_timing.items() if k not in PLAN_PARTS | {"serialize"})


class ServerTimingTransport(httpx.HTTPTransport):
    """The HTTP transport, keeping the Server-Timing header of the last answer."""

    last = ""

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        """Send `request`; note its answer's Server-Timing header."""
        response = super().handle_request(request)
        self.last = response.headers.get("server-timing", "")
        return response


class TimedClient(Client):
    """The Python client, not retrying, noting each answer's Server-Timing header."""

    def __init__(self, base: str, timeout_s: float) -> None:
        self.timing = ServerTimingTransport()
        super().__init__(base, timeout=timeout_s, retry=NO_RETRY, transport=self.timing)


def api_client(base: str, timeout_s: float) -> TimedClient:
    """A client of the service for the benchmark."""
    return TimedClient(base, timeout_s)


def send(client: TimedClient, query: Query) -> Sample:
    """Send one plan request with the Python client and time it."""
    body = query.body
    began = time.perf_counter()
    try:
        answer = client.plan(query.robot_id, body["start"], body["goal"], body["options"])
    except APIError as exc:
        raise RuntimeError(f"plan answered {exc.status_code}: {exc.detail[:300]}") from exc
    latency = (time.perf_counter() - began) * 1e3
    timing = _server_timing(client.timing.last)
    return Sample(latency, answer.source == "cache", answer.timings_ms, timing)


def send_lean(conn: http.client.HTTPConnection, query: Query) -> Sample:
    """Send one plan request with http.client on a keep-alive connection and time it."""
    began = time.perf_counter()
    conn.request(
        "POST",
        f"/v1/robots/{query.robot_id}/plan",
        body=json.dumps(query.body).encode(),
        headers={"content-type": "application/json"},
    )
    reply = conn.getresponse()
    data = reply.read()
    latency = (time.perf_counter() - began) * 1e3
    if reply.status != 200:
        raise RuntimeError(f"plan answered {reply.status}: {data[:300]!r}")
    return _sample(latency, json.loads(data), reply.getheader("server-timing", ""))


def _sample(latency: float, body: dict[str, Any], server_timing: str) -> Sample:
    return Sample(
        latency,
        body.get("source") == "cache",
        body.get("timings_ms", {}),
        _server_timing(server_timing),
    )


def _server_timing(header: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for part in header.split(","):
        name, _, rest = part.strip().partition(";dur=")
        if rest:
            out[name] = float(rest)
    return out


def run_sequential(base: str, queries: list[Query]) -> list[Sample]:
    """Each query once, one Python client, in order."""
    with api_client(base, 30) as client:
        return [send(client, q) for q in queries]


def run_both(base: str, queries: list[Query]) -> tuple[list[Sample], list[Sample]]:
    """Each query once, in order, the lean and the Python client taking turns: (lean, python)."""
    url = httpx.URL(base)
    lean: list[Sample] = []
    other: list[Sample] = []
    conn = http.client.HTTPConnection(url.host, url.port, timeout=30)
    try:
        with api_client(base, 30) as client:
            for k, query in enumerate(queries):
                if k % 2 == 0:
                    lean.append(send_lean(conn, query))
                else:
                    other.append(send(client, query))
    finally:
        conn.close()
    return lean, other


def http_floor(base: str, n: int = 200) -> tuple[float, float]:
    """Median latency (ms) of GET /healthz, transport and framework only: (lean, python)."""
    url = httpx.URL(base)
    conn = http.client.HTTPConnection(url.host, url.port, timeout=30)
    lean, other = [], []
    try:
        with api_client(base, 30) as client:
            for _ in range(n):
                began = time.perf_counter()
                conn.request("GET", "/healthz")
                reply = conn.getresponse()
                json.loads(reply.read())
                lean.append((time.perf_counter() - began) * 1e3)
                began = time.perf_counter()
                client.health()
                other.append((time.perf_counter() - began) * 1e3)
    finally:
        conn.close()
    return statistics.median(lean), statistics.median(other)


def run_concurrent(base: str, queries: list[Query]) -> tuple[float, int]:
    """Plans per second and hits with CONCURRENCY clients, each sending its share in order."""
    shares = [queries[k::CONCURRENCY] for k in range(CONCURRENCY)]
    hits = [0] * CONCURRENCY
    errors: list[str] = []

    def worker(k: int) -> None:
        with api_client(base, 60) as client:
            try:
                hits[k] = sum(send(client, q).hit for q in shares[k])
            except Exception as exc:  # reported below
                errors.append(str(exc))

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(CONCURRENCY)]
    began = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    elapsed = time.perf_counter() - began
    if errors:
        raise RuntimeError(f"{len(errors)} clients failed, first: {errors[0][:300]}")
    return len(queries) / elapsed, sum(hits)
