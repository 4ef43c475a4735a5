"""Error answers and failed connections become the client's exceptions (httpx.MockTransport)."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

import trajcache_client as tc
from trajcache_client import NO_RETRY, Client


def _answering(status: int, **response: Any) -> Client:
    """A client of a service that answers every request with `status` and `response`."""
    content = response or {"json": {"detail": f"status {status}"}}

    def handler(request: httpx.Request) -> httpx.Response:
        return httpx.Response(status, **content)

    return Client("http://svc", retry=NO_RETRY, transport=httpx.MockTransport(handler))


@pytest.mark.parametrize(
    ("status", "kind"),
    [
        (400, tc.BadRequestError),
        (401, tc.AuthError),
        (403, tc.AuthError),
        (404, tc.NotFoundError),
        (409, tc.ConflictError),
        (413, tc.PayloadTooLargeError),
        (415, tc.UnsupportedMediaTypeError),
        (422, tc.ValidationError),
        (418, tc.APIError),
        (500, tc.ServerError),
        (503, tc.UnavailableError),
    ],
)
def test_error_status_raises_its_exception(status: int, kind: type[tc.APIError]) -> None:
    with _answering(status) as client, pytest.raises(kind) as caught:
        client.get_robot("r1")
    error = caught.value
    assert type(error) is kind and isinstance(error, tc.TrajcacheError)
    assert error.status_code == status and error.detail == f"status {status}"
    assert str(error) == f"{status} GET /v1/robots/r1: status {status}"


def test_unavailable_is_a_server_error_and_auth_errors_are_api_errors() -> None:
    assert issubclass(tc.UnavailableError, tc.ServerError)
    assert issubclass(tc.ServerError, tc.APIError)
    assert issubclass(tc.AuthError, tc.APIError)
    assert issubclass(tc.TransportTimeoutError, tc.TransportError)
    assert not issubclass(tc.TransportError, tc.APIError)


def test_validation_error_lists_the_fields() -> None:
    body = {
        "detail": "body.start[1]: Input should be a finite number",
        "errors": [{"loc": ["body", "start", 1], "msg": "finite", "type": "finite_number"}],
    }
    with _answering(422, json=body) as client, pytest.raises(tc.ValidationError) as caught:
        client.plan("r1", [0.0, 0.0], [1.0, 1.0])
    assert caught.value.detail == body["detail"]
    assert caught.value.errors == body["errors"]


def test_list_detail_of_a_default_validation_answer_is_read() -> None:
    body = {"detail": [{"loc": ["body", "goal"], "msg": "Field required", "type": "missing"}]}
    with _answering(422, json=body) as client, pytest.raises(tc.ValidationError) as caught:
        client.plan("r1", [0.0], [1.0])
    assert caught.value.detail == "Field required"
    assert caught.value.errors[0]["loc"] == ["body", "goal"]


def test_a_proxy_error_page_becomes_a_server_error_with_its_text() -> None:
    page = "<html><body>502 Bad Gateway</body></html>"
    with _answering(502, text=page) as client, pytest.raises(tc.ServerError) as caught:
        client.health()
    assert "502 Bad Gateway" in caught.value.detail


def test_a_success_body_of_the_wrong_shape_is_an_unexpected_response() -> None:
    with (
        _answering(200, json={"robot_id": "r1"}) as client,
        pytest.raises(tc.UnexpectedResponseError, match="not a Robot") as caught,
    ):
        client.get_robot("r1")
    assert caught.value.response.status_code == 200


@pytest.fixture
def silent_port() -> Iterator[int]:
    """A loopback port that accepts connections and never answers."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    held: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        server.settimeout(0.1)
        while not stop.is_set():
            try:
                held.append(server.accept()[0])
            except OSError:
                continue

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    yield server.getsockname()[1]
    stop.set()
    thread.join()
    for conn in held:
        conn.close()
    server.close()


def test_a_service_that_does_not_answer_times_out(silent_port: int) -> None:
    url = f"http://127.0.0.1:{silent_port}"
    with (
        Client(url, timeout=0.2, retry=NO_RETRY) as client,
        pytest.raises(tc.TransportTimeoutError, match="ReadTimeout") as caught,
    ):
        client.health()
    assert caught.value.request is not None and caught.value.request.url.path == "/healthz"


def test_a_refused_connection_is_a_transport_error() -> None:
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # nothing listens there now
    with (
        Client(f"http://127.0.0.1:{port}", retry=NO_RETRY) as client,
        pytest.raises(tc.TransportError, match="ConnectError") as caught,
    ):
        client.get_robot("r1")
    assert not isinstance(caught.value, tc.TransportTimeoutError)
