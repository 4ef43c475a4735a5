"""Quality at store time (`services.quality`, through `store_trajectory`), and a model's
configuration read back from the database."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from tests.robots import TWO_JOINT_URDF
from tests.services.hit_setup import context
from trajcache.core.config import Settings
from trajcache.db.models import Trajectory
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.space import path_length
from trajcache.geometry.path_quality import ee_path_length, min_clearance
from trajcache.geometry.scene.parse import parse_scene
from trajcache.services.catalog.models import (
    ModelRegistration,
    ModelRegistry,
    get_model,
    register_model,
)
from trajcache.services.catalog.trajectories import NewTrajectory, store_trajectory
from trajcache.services.context import ServiceContext

BALL = {"id": "ball", "type": "sphere", "size": [0.05], "pose": {"position": [0.4, 0, 0.2]}}
SCENE = parse_scene({"objects": [BALL]})


@pytest.fixture
def ctx(tmp_path: Path) -> Iterator[ServiceContext]:
    with context(f"sqlite:///{tmp_path / 'q.db'}", worker_prestart=False) as service:
        yield service


def test_store_computes_quality_columns(ctx: ServiceContext) -> None:
    states = np.array([[0.0, 0.0], [0.5, 0.2], [0.2, 0.6]])
    with ctx.sessions() as session:
        model, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(urdf=TWO_JOINT_URDF),
        )
        with_scene, _ = store_trajectory(
            session=session,
            settings=Settings(),
            trajectory=NewTrajectory(model=model, states=states, source="sim", scene=SCENE),
        )
        plain, _ = store_trajectory(
            session=session,
            settings=Settings(),
            compute_quality=False,
            trajectory=NewTrajectory(model=model, states=states[:2], source="sim"),
        )
        row = session.get(Trajectory, with_scene)
        assert row is not None
        assert row.length == pytest.approx(path_length(states, base=BaseType.FIXED))
        assert row.ee_length == pytest.approx(ee_path_length(model, states))
        found = min_clearance(CollisionChecker(model, SCENE), states)
        assert found is not None and row.min_clearance == pytest.approx(found.distance)
        assert row.duration_s is not None and row.duration_s > 0
        assert row.quality is not None and row.quality["clearance"]["object"] == "ball"
        bare = session.get(Trajectory, plain)
        assert bare is not None
        assert (bare.length, bare.ee_length, bare.min_clearance, bare.duration_s) == (None,) * 4


def test_a_fresh_registry_loads_the_configuration_from_the_database(
    ctx: ServiceContext,
) -> None:
    with ctx.sessions() as session:
        model, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(
                urdf=TWO_JOINT_URDF, acceleration_limits={"elbow": 2.0}, end_effector_link="upper"
            ),
        )
        loaded = get_model(session=session, registry=ModelRegistry(), model_id=model.model_id)
    for m in (model, loaded):
        assert m.acceleration_limits is not None
        assert np.isnan(m.acceleration_limits[0]) and m.acceleration_limits[1] == 2.0
        assert m.jerk_limits is None and m.end_effector_link == "upper"
