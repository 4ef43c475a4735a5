"""Seed jobs' tests share a service context with quick job timings and a two-joint model."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.robots import TWO_JOINT_URDF
from trajcache.core.config import Settings
from trajcache.geometry.model.robot import RobotModel
from trajcache.services.catalog.models import ModelRegistration, register_model
from trajcache.services.context import ServiceContext


def register_two_joint(ctx: ServiceContext) -> RobotModel:
    """The two-joint test model, registered in `ctx`'s database."""
    with ctx.sessions() as session:
        model, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(urdf=TWO_JOINT_URDF),
        )
    return model


@pytest.fixture
def ctx(migrated_url: str) -> Iterator[ServiceContext]:
    """No planner pool (jobs plan nothing), heartbeats and polls every 0.1 s, 5 s leases."""
    context = ServiceContext.create(
        Settings(
            database_url=migrated_url,
            worker_backend="none",
            seed_heartbeat_s=0.1,
            seed_lease_s=5.0,
            seed_poll_interval_s=0.1,
        )
    )
    yield context
    context.close()


@pytest.fixture
def model_id(ctx: ServiceContext) -> str:
    return register_two_joint(ctx).model_id
