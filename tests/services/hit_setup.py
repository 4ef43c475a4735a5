"""Shared set-up of the cache-hit tests: real service contexts on a migrated database."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import sqlalchemy as sa

from tests.robots import TWO_JOINT_URDF
from trajcache.core.config import Settings
from trajcache.db import migrate
from trajcache.geometry.model.robot import RobotModel
from trajcache.services.catalog.models import ModelRegistration, register_model
from trajcache.services.catalog.trajectories import NewTrajectory, store_trajectory
from trajcache.services.context import ServiceContext


@contextmanager
def context(url: str, **settings: Any) -> Iterator[ServiceContext]:
    """A service context (one replica) on the database at `url`, migrated; closed afterwards."""
    migrate.upgrade(url)
    ctx = ServiceContext.create(Settings(database_url=url, **settings))
    try:
        yield ctx
    finally:
        ctx.close()


def two_joint(ctx: ServiceContext, *, base: str = "fixed") -> RobotModel:
    """The small two-joint arm (on a planar base if asked), registered."""
    with ctx.sessions() as session:
        model, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(urdf=TWO_JOINT_URDF, base=base),
        )
    return model


def store(ctx: ServiceContext, model: RobotModel, states: list[list[float]]) -> int:
    """Store a trajectory (without quality metrics) and return its id."""
    with ctx.sessions() as session:
        trajectory_id, _ = store_trajectory(
            session=session,
            settings=Settings(),
            compute_quality=False,
            trajectory=NewTrajectory(
                model=model, states=np.asarray(states, dtype=float), source="sim"
            ),
        )
    return trajectory_id


@contextmanager
def count_statements(engine: sa.Engine) -> Iterator[list[str]]:
    """SQL statements sent through `engine` while the block runs."""
    statements: list[str] = []

    def record(_conn: Any, _cursor: Any, statement: str, *_args: Any) -> None:
        statements.append(statement)

    sa.event.listen(engine, "before_cursor_execute", record)
    try:
        yield statements
    finally:
        sa.event.remove(engine, "before_cursor_execute", record)
