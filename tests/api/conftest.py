"""API fixtures: the real app (lifespan, migrations) on a SQLite file and on PostgreSQL."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.robots import TWO_JOINT_URDF
from trajcache.core.config import Settings
from trajcache.main import create_app
from trajcache.reference import robot as reference_robot
from trajcache.services.context import ServiceContext

ClientFactory = Callable[..., TestClient]


@pytest.fixture
def client_factory(database_url: str) -> Iterator[ClientFactory]:
    """Start apps (lifespan included) on the test database with some settings overridden."""
    with ExitStack() as stack:

        def make(**overrides: Any) -> TestClient:
            # Planner workers start on the first miss that needs them, not with every test app.
            overrides.setdefault("worker_prestart", False)
            settings = Settings(database_url=database_url, **overrides)
            return stack.enter_context(TestClient(create_app(settings)))

        yield make


@pytest.fixture
def app_client(client_factory: ClientFactory) -> TestClient:
    """A client of the app with default settings."""
    return client_factory()


def ctx_of(client: TestClient) -> ServiceContext:
    """The ServiceContext of the app behind `client`."""
    ctx: ServiceContext = client.app.state.ctx  # type: ignore[attr-defined]
    return ctx


@pytest.fixture
def two_joint_urdf() -> str:
    """URDF text of the small 2-joint test arm."""
    return TWO_JOINT_URDF


@pytest.fixture
def reference_urdf() -> str:
    """URDF text of the reference robot."""
    return reference_robot.reference_urdf()


def register(client: TestClient, urdf: str = TWO_JOINT_URDF, **fields: Any) -> dict[str, Any]:
    """Register a model through the API and return the response body."""
    response = client.post("/v1/robot-models", json={"urdf": urdf, **fields})
    assert response.status_code in (200, 201), response.text
    body: dict[str, Any] = response.json()
    return body


@pytest.fixture
def model_id(app_client: TestClient) -> str:
    """Id of the 2-joint model, registered."""
    return str(register(app_client)["model_id"])


@pytest.fixture
def robot_id(app_client: TestClient, model_id: str) -> str:
    """A robot of the 2-joint model."""
    response = app_client.put("/v1/robots/robot-1", json={"model_id": model_id})
    assert response.status_code == 201, response.text
    return "robot-1"


def assert_detail(response: Any, status: int, *needles: str) -> str:
    """Check the status and that `detail` is a string containing every needle."""
    assert response.status_code == status, response.text
    detail = response.json()["detail"]
    assert isinstance(detail, str) and detail
    for needle in needles:
        assert needle in detail, f"{needle!r} not in {detail!r}"
    return detail
