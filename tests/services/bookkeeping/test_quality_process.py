"""A planned trajectory's quality columns, computed in the quality process."""

from __future__ import annotations

import os
import signal

import numpy as np

from tests.robots import BOXED_TWO_LINK_URDF
from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.geometry.scene.parse import parse_scene
from trajcache.planning.problem import ModelSource
from trajcache.planning.run import model_from_source
from trajcache.services.bookkeeping import quality_process
from trajcache.services.bookkeeping.quality_process import quality_elsewhere
from trajcache.services.catalog.trajectories import quality_columns

SOURCE = ModelSource("two-link", BOXED_TWO_LINK_URDF, "fixed", ("shoulder", "elbow"))
SCENE = parse_scene(
    {"objects": [{"id": "wall", "type": "box", "size": [0.1, 0.1, 0.5],
                  "pose": {"position": [0.0, 0.45, 0.0]}}]}
)  # fmt: skip
PATH = np.array([[0.0, 0.0], [-0.6, 0.3], [-1.2, 0.2]])


def test_the_columns_are_those_the_service_would_compute_itself() -> None:
    settings = Settings()
    here = quality_columns(model_from_source(SOURCE), PATH, settings, SCENE)
    there = quality_elsewhere(SOURCE, PATH, settings, SCENE)
    assert here is not None and there is not None
    assert _same(here, there)
    assert there["duration_s"] > 0 and there["min_clearance"] > 0  # every metric is there
    assert quality_elsewhere(SOURCE, PATH, settings, None)["min_clearance"] is None  # no scene


def test_a_process_that_died_between_jobs_is_replaced_for_the_next() -> None:
    settings = Settings()
    assert quality_elsewhere(SOURCE, PATH, settings, SCENE) is not None  # the process is up
    executor = quality_process._PROCESS._executor
    assert executor is not None
    [pid] = list(executor._processes)  # type: ignore[attr-defined]
    os.kill(pid, signal.SIGKILL)
    wait_until(lambda: getattr(executor, "_broken", False))
    after = quality_elsewhere(SOURCE, PATH, settings, SCENE)
    assert after is not None and after["duration_s"] > 0
    assert quality_process._PROCESS._executor is not executor


def _same(a: object, b: object) -> bool:
    """Equal, floats to 1e-9, through nested mappings and lists."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float):
        return abs(a - b) <= 1e-9 * max(1.0, abs(a))
    return a == b
