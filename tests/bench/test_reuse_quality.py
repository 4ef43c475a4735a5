"""bench/reuse_quality.py: the fresh plan of a query and the cached / fresh ratios."""

from __future__ import annotations

import numpy as np
import pytest

from reuse_quality import Hit, _same_path, plan_fresh, ratios
from trajcache.core.config import Settings
from trajcache.geometry.path_quality import Quality
from trajcache.planning.problem import ModelSource
from trajcache.reference.cleaning import cleaning_run
from trajcache.reference.robot import REFERENCE_BASE, reference_model, reference_urdf


def _hit(cached: dict[str, float | None], fresh: Quality | None) -> Hit:
    run = cleaning_run(1)
    call = run.calls[2]
    return Hit(1, call, run.scene_for(call), np.stack([call.start, call.goal]), cached, fresh)


def test_ratios_skip_missing_values_and_same_paths_are_recognised() -> None:
    fresh = Quality(2.0, 1.0, 0.1, 4.0)
    hits = [
        _hit({"path_length": 2.2, "duration_s": 4.0, "min_clearance": None}, fresh),
        _hit({"path_length": 2.0, "duration_s": 5.0, "min_clearance": 0.05}, fresh),
        _hit({"path_length": 2.0, "duration_s": 5.0, "min_clearance": 0.05}, None),
    ]
    assert ratios(hits, "path_length") == pytest.approx([1.1, 1.0])
    assert ratios(hits, "min_clearance") == pytest.approx([0.5])
    assert [_same_path(h) for h in hits] == [False, True, False]


def test_fresh_plan_of_a_workload_call_is_measured_in_its_scene() -> None:
    model = reference_model()
    source = ModelSource(
        model_id=model.model_id,
        urdf=reference_urdf(),
        base=REFERENCE_BASE,
        joint_names=model.joint_names,
    )
    hit = _hit({}, None)
    quality = plan_fresh(model, source, hit, Settings())
    assert quality is not None
    straight = float(np.linalg.norm(hit.call.goal - hit.call.start))
    assert quality.path_length >= straight - 1e-9
    assert quality.duration_s is not None and quality.duration_s > 0
    assert quality.min_clearance is not None and quality.min_clearance > 0
