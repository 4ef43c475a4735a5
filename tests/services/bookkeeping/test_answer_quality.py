"""Answer quality (`services.bookkeeping.answer_quality`): computed with the model and scene the
plan validated, and the settings and validators it is handed, without reading the database."""

from __future__ import annotations

import functools
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from tests.robots import TWO_JOINT_URDF, two_joint_arm
from tests.services.hit_setup import context, count_statements
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.path_quality import ee_path_length, min_clearance
from trajcache.geometry.scene.parse import parse_scene
from trajcache.services.bookkeeping.answer_quality import QualityLevel, answer_details
from trajcache.services.catalog.models import ModelRegistration, register_model
from trajcache.services.context import ServiceContext
from trajcache.services.quality import TimingRequest
from trajcache.timing import PathShape, TimingMethod

OTHER_URDF = two_joint_arm(name="other", elbow_limit=1.4)
BALL = {"id": "ball", "type": "sphere", "size": [0.05], "pose": {"position": [0.4, 0, 0.2]}}
SCENE = parse_scene({"objects": [BALL]})


@pytest.fixture
def ctx(tmp_path: Path) -> Iterator[ServiceContext]:
    with context(f"sqlite:///{tmp_path / 'q.db'}", worker_prestart=False) as service:
        yield service


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
    details = functools.partial(answer_details, settings=ctx.settings, validators=ctx.validators)
    with count_statements(ctx.engine) as statements:
        basic = details(
            model=first, scene=empty, states=states, timing=None, level=QualityLevel.BASIC
        )
        other = details(
            model=second, scene=empty, states=states, timing=None, level=QualityLevel.BASIC
        )
        timed = details(
            model=first,
            scene=SCENE,
            states=states,
            timing=TimingRequest(TimingMethod.TOPPRA, PathShape.LINEAR, sample_period_s=0.1),
            level=QualityLevel.FULL,
        )
        bare = details(
            model=first, scene=empty, states=states, timing=None, level=QualityLevel.FULL
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
