"""API fixtures: the real app (lifespan, migrations) on a SQLite file and on PostgreSQL."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from trajcache.core.config import Settings
from trajcache.main import create_app
from trajcache.services.context import ServiceContext

# A fixed-base arm with two revolute joints; link geometry keeps the allowed-pair sampling quick.
TWO_JOINT_URDF = """<?xml version="1.0"?>
<robot name="two_joint">
  <link name="base">
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.2 0.2 0.1"/></geometry></collision>
  </link>
  <link name="upper">
    <collision><origin xyz="0 0 0.15"/><geometry><cylinder radius="0.03" length="0.3"/>
    </geometry></collision>
  </link>
  <link name="fore">
    <collision><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.02" length="0.2"/>
    </geometry></collision>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>
    <limit lower="-2.0" upper="2.0" effort="1" velocity="1"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="fore"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="1" velocity="1"/>
  </joint>
</robot>
"""

ClientFactory = Callable[..., TestClient]


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def database_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """An empty database: a SQLite file, or a fresh PostgreSQL schema."""
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'api.db'}"
    return str(request.getfixturevalue("postgres_url"))


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
    """URDF text of the reference robot (skipped if that module is not there)."""
    robot = pytest.importorskip("trajcache.geometry.reference.robot")
    return str(robot.reference_urdf())


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
