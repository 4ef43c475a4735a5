"""Quality at store time, model configuration from the database, and answer quality."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from tests.robots import TWO_JOINT_URDF, two_joint_arm
from tests.services.hit_setup import count_statements
from trajcache.core.config import Settings
from trajcache.db import migrate
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
from trajcache.services.plan.quality import QualityLevel, answer_details
from trajcache.services.quality import TimingRequest
from trajcache.timing import PathShape, TimingMethod

OTHER_URDF = two_joint_arm(name="other", elbow_limit=1.4)
BALL = {"id": "ball", "type": "sphere", "size": [0.05], "pose": {"position": [0.4, 0, 0.2]}}
SCENE = parse_scene({"objects": [BALL]})


@pytest.fixture
def ctx(tmp_path: Path) -> Iterator[ServiceContext]:
    url = f"sqlite:///{tmp_path / 'q.db'}"
    migrate.upgrade(url)
    context = ServiceContext.create(Settings(database_url=url, worker_prestart=False))
    try:
        yield context
    finally:
        context.close()


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


def test_answer_quality_uses_the_model_and_scene_of_the_plan_without_reading_them(
    ctx: ServiceContext,
) -> None:
    with ctx.sessions() as session:
        first, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(urdf=TWO_JOINT_URDF),
        )
        second, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(urdf=OTHER_URDF, end_effector_link="upper"),
        )
    states = np.array([[0.0, 0.0], [1.0, 0.5]])
    empty = parse_scene({"objects": []})
    with count_statements(ctx.engine) as statements:
        basic = answer_details(
            ctx=ctx, model=first, scene=empty, states=states, timing=None, level=QualityLevel.BASIC
        )
        other = answer_details(
            ctx=ctx, model=second, scene=empty, states=states, timing=None, level=QualityLevel.BASIC
        )
        timed = answer_details(
            ctx=ctx,
            model=first,
            scene=SCENE,
            states=states,
            timing=TimingRequest(TimingMethod.TOPPRA, PathShape.LINEAR, sample_period_s=0.1),
            level=QualityLevel.FULL,
        )
        bare = answer_details(
            ctx=ctx, model=first, scene=empty, states=states, timing=None, level=QualityLevel.FULL
        )
    assert statements == []
    assert basic.quality.ee_path_length == pytest.approx(ee_path_length(first, states))
    assert other.quality.ee_path_length == pytest.approx(ee_path_length(second, states))
    assert basic.quality.ee_path_length != pytest.approx(other.quality.ee_path_length)
    assert basic.quality.min_clearance is None and basic.timed is None
    assert timed.timed is not None and timed.samples is not None
    assert timed.quality.duration_s == pytest.approx(timed.timed.duration)
    found = min_clearance(CollisionChecker(first, SCENE), states)
    assert found is not None and timed.quality.min_clearance == pytest.approx(found.distance)
    assert set(timed.timings_ms) == {"timing", "quality"}
    assert bare.quality.min_clearance is None and bare.quality.duration_s is not None
