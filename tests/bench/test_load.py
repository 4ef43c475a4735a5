"""bench/load.py: the robots' scripts, and the smoke run end to end on two replicas."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from load_scripts import MissMaker, robot_script
from tests.conftest import POSTGRES_URL, require_service
from trajcache.reference.cleaning import cleaning_run
from trajcache.reference.robot import reference_model

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "load.py"


def test_scripts_keep_the_scene_current_and_replace_a_tenth_of_the_calls() -> None:
    steps = robot_script("r", [cleaning_run(5)], 60, MissMaker(reference_model(), 0), share=0.1)
    plans = [s for s in steps if s.kind != "scene"]
    assert len(plans) == 60 and sum(s.kind == "miss" for s in plans) == 6
    assert steps[0].kind == "scene" and steps[0].method == "PUT"
    assert all(s.method == "PATCH" for s in steps[1:] if s.kind == "scene")
    assert all(s.path == "/v1/robots/r/plan" for s in plans)


def test_misses_are_beyond_the_lookup_threshold_within_limits_and_collision_free() -> None:
    model = reference_model()
    run = cleaning_run(5)
    misses = MissMaker(model, seed=0)
    for call in [c for c in run.calls if not c.base_moves][:20]:
        scene = run.scene_for(call)
        made = misses.make(call, scene)
        assert made is not None
        for moved, original in zip(made, (call.start, call.goal), strict=True):
            assert np.array_equal(moved[:3], original[:3])  # the base stays
            assert np.max(np.abs(moved[3:] - original[3:])) > 0.2  # the lookup threshold
            assert np.all(moved[3:] >= model.lower[3:]) and np.all(moved[3:] <= model.upper[3:])
            assert misses._free(scene, moved)


@pytest.mark.slow
@pytest.mark.postgres
def test_smoke_run_plans_without_errors_and_loses_nothing() -> None:
    require_service("PostgreSQL", "127.0.0.1", 5432)
    cmd = [sys.executable, str(SCRIPT), "--smoke", "--database-url", POSTGRES_URL]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=280, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    assert summary["errors"] == 0, done.stdout[-3000:]
    assert summary["lost"] == 0
    assert (summary["robots"], summary["replicas"]) == (8, 2)
    assert summary["plans"] > 0 and summary["plans_per_s"] > 0
    assert summary["planned"] > 0  # misses reached the planner and were checked afterwards
    assert 0.5 < summary["hit_share"] < 1.0
    assert summary["p50_ms"] > 0 and summary["p99_ms"] >= summary["p50_ms"]
