"""Which calls are retried, how often and how long the client waits (httpx.MockTransport)."""

from __future__ import annotations

import email.utils
import time
from types import SimpleNamespace
from typing import Any

import httpx
import pytest

import trajcache_client as tc
from tests.client.conftest import FAST_RETRY
from trajcache_client import AsyncClient, Client, Retry
from trajcache_client import _client as _client_module

ROBOT = {
    "robot_id": "r1",
    "model_id": "m1",
    "kind": "real",
    "scene_version": 0,
    "created_at": "2025-06-02T09:25:01Z",
    "updated_at": "2025-06-02T09:25:01Z",
}
PLAN = {
    "status": "success",
    "source": "cache",
    "trajectory_id": 7,
    "states": [[0.0, 0.0], [1.0, 1.0]],
    "candidates_tried": 1,
    "timings_ms": {"lookup": 0.1, "validate": 1.0, "plan": 0.0, "total": 1.5},
}


class Script:
    """A MockTransport handler that answers from a script and records what it was sent."""

    def __init__(self, *answers: int | Exception | httpx.Response, ok: Any = None) -> None:
        self.answers = list(answers)
        self.ok = ok
        self.requests: list[httpx.Request] = []

    def __call__(self, request: httpx.Request) -> httpx.Response:
        self.requests.append(request)
        answer = self.answers.pop(0) if self.answers else 200
        if isinstance(answer, Exception):
            raise answer
        if isinstance(answer, httpx.Response):
            return answer
        if answer == 200:
            return httpx.Response(200, json=self.ok)
        return httpx.Response(answer, json={"detail": f"status {answer}"})


def _client(script: Script, retry: Retry = FAST_RETRY) -> Client:
    return Client("http://svc", retry=retry, transport=httpx.MockTransport(script))


def _connect_error() -> httpx.ConnectError:
    return httpx.ConnectError("connection refused")


def _read_timeout() -> httpx.ReadTimeout:
    return httpx.ReadTimeout("timed out")


@pytest.mark.parametrize("failure", [503, 502, 504, _connect_error(), _read_timeout()])
def test_a_read_is_retried_until_it_succeeds(failure: int | Exception) -> None:
    script = Script(failure, failure, ok=ROBOT)
    with _client(script) as client:
        robot = client.get_robot("r1")
    assert robot.robot_id == "r1" and len(script.requests) == 3


def test_retries_stop_after_the_configured_number() -> None:
    script = Script(503, 503, 503, 503, ok=ROBOT)
    with _client(script) as client, pytest.raises(tc.UnavailableError):
        client.get_robot("r1")
    assert len(script.requests) == 3  # the first try and FAST_RETRY.retries == 2 more


@pytest.mark.parametrize("status", [400, 404, 409, 422, 500])
def test_other_error_statuses_are_not_retried(status: int) -> None:
    script = Script(status, ok=ROBOT)
    with _client(script) as client, pytest.raises(tc.APIError):
        client.get_robot("r1")
    assert len(script.requests) == 1


@pytest.mark.parametrize("failure", [503, _connect_error()])
def test_plan_is_retried_on_503_and_when_the_request_was_never_sent(
    failure: int | Exception,
) -> None:
    script = Script(failure, ok=PLAN)
    with _client(script) as client:
        answer = client.plan("r1", [0, 0], [1, 1])
    assert answer.ok and len(script.requests) == 2


@pytest.mark.parametrize(
    ("failure", "raised"),
    [
        (502, tc.ServerError),
        (504, tc.ServerError),
        (_read_timeout(), tc.TransportTimeoutError),
        (httpx.RemoteProtocolError("server disconnected"), tc.TransportError),
    ],
)
def test_plan_is_not_retried_when_it_may_have_been_processed(
    failure: int | Exception, raised: type[Exception]
) -> None:
    script = Script(failure, ok=PLAN)
    with _client(script) as client, pytest.raises(raised):
        client.plan("r1", [0, 0], [1, 1])
    assert len(script.requests) == 1


def test_scene_patch_is_not_retried_on_a_gateway_error() -> None:
    script = Script(502, ok={"version": 2, "hash": "h"})
    with _client(script) as client, pytest.raises(tc.ServerError):
        client.patch_scene("r1", remove=["cart"])
    assert len(script.requests) == 1


def test_content_addressed_posts_are_retried_like_reads() -> None:
    stored = {"trajectory_id": 3, "created": True}
    script = Script(502, _read_timeout(), ok=stored)
    with _client(script) as client:
        assert client.store_trajectory("m1", [[0, 0], [1, 1]]).trajectory_id == 3
    assert len(script.requests) == 3
    assert script.requests[0].content == script.requests[2].content


def test_a_mistake_on_the_client_side_is_not_retried() -> None:
    script = Script(httpx.UnsupportedProtocol("unsupported scheme 'ftp'"), ok=ROBOT)
    with _client(script) as client, pytest.raises(tc.TransportError, match="UnsupportedProtocol"):
        client.get_robot("r1")
    assert len(script.requests) == 1


def test_readiness_probe_is_never_retried() -> None:
    script = Script(503, ok={"status": "ready"})
    with _client(script) as client, pytest.raises(tc.UnavailableError):
        client.ready()
    assert len(script.requests) == 1


def test_no_retry_policy_sends_once() -> None:
    script = Script(503, ok=ROBOT)
    with _client(script, tc.NO_RETRY) as client, pytest.raises(tc.UnavailableError):
        client.get_robot("r1")
    assert len(script.requests) == 1


def test_the_client_waits_between_tries(monkeypatch: pytest.MonkeyPatch) -> None:
    script = Script(503, 503, ok=ROBOT)
    retry = Retry(retries=2, backoff_s=0.05, jitter=0.0)
    waits: list[float] = []
    monkeypatch.setattr(_client_module, "time", SimpleNamespace(sleep=waits.append))
    with _client(script, retry) as client:
        client.get_robot("r1")
    assert waits == [0.05, 0.1]  # 0.05 s, then 0.1 s
    assert len(script.requests) == 3


def test_delays_grow_exponentially_within_the_jitter_and_the_cap() -> None:
    retry = Retry(retries=10, backoff_s=0.1, backoff_max_s=1.0, jitter=0.5)
    for n, full in enumerate([0.1, 0.2, 0.4, 0.8, 1.0, 1.0]):
        delays = [retry.delay(n) for _ in range(200)]
        assert all(full * 0.5 <= d <= full for d in delays)
        assert max(delays) - min(delays) > full * 0.2  # jittered, not constant


def test_retry_after_is_honoured_up_to_the_cap() -> None:
    retry = Retry(backoff_s=0.1, backoff_max_s=5.0, jitter=0.0)
    assert retry.delay(0, httpx.Response(503, headers={"retry-after": "2"})) == 2.0
    assert retry.delay(0, httpx.Response(503, headers={"retry-after": "60"})) == 5.0
    assert retry.delay(0, httpx.Response(503, headers={"retry-after": "soon"})) == 0.1
    later = email.utils.formatdate(time.time() + 3, usegmt=True)
    assert 1.5 < retry.delay(0, httpx.Response(503, headers={"retry-after": later})) <= 3.0


@pytest.mark.parametrize(
    "bad", [{"retries": -1}, {"backoff_s": -0.1}, {"backoff_max_s": -1}, {"jitter": 1.5}]
)
def test_an_invalid_policy_is_refused(bad: dict[str, Any]) -> None:
    with pytest.raises(ValueError):
        Retry(**bad)


@pytest.mark.anyio
async def test_the_async_client_retries_the_same_way() -> None:
    script = Script(503, _connect_error(), ok=PLAN)
    transport = httpx.MockTransport(script)
    async with AsyncClient("http://svc", retry=FAST_RETRY, transport=transport) as client:
        assert (await client.plan("r1", [0, 0], [1, 1])).ok
        assert len(script.requests) == 3
        script.answers = [502]
        with pytest.raises(tc.ServerError):
            await client.plan("r1", [0, 0], [1, 1])
        assert len(script.requests) == 4
