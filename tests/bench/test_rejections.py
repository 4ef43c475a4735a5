"""bench/rejections.py: the box it places blocks a motion and spares its ends; a smoke run
explains every rejection it causes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from rejections import _blocked
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.validation.validator import TrajectoryValidator, ValidationStatus
from trajcache.reference.cleaning import cleaning_run
from trajcache.reference.robot import reference_urdf

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "rejections.py"


def test_the_box_blocks_the_motion_and_leaves_its_ends_clear() -> None:
    model = load_robot_model(reference_urdf(), base="planar")
    run = cleaning_run(11)
    found = 0
    for call in [c for c in run.calls if not c.base_moves][:20]:
        scene, path = run.scene_for(call), np.stack([call.start, call.goal])
        blocked = _blocked(model, scene, path)
        if blocked is None:
            continue
        found += 1
        validator = TrajectoryValidator(model, blocked)
        assert validator.validate(path).status is ValidationStatus.COLLISION
        assert not validator.checker.state_contacts(path[0])
        assert not validator.checker.state_contacts(path[-1])
        assert [o.id for o in blocked.objects][-1] == "cart"
        free = TrajectoryValidator(model, scene).validate(path).status
        assert free is ValidationStatus.VALID  # the box, not the scene, blocks it
    assert found >= 3


def test_a_smoke_run_explains_every_rejection() -> None:
    out = subprocess.run(
        [sys.executable, str(SCRIPT), "--smoke"], capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    figures = json.loads(out.stdout.strip().splitlines()[-1])
    assert figures["cases"] >= 1 and figures["rejected_per_miss"] >= 1
    assert figures["events_explained"] == figures["events_listed"] > 0
    assert figures["explain_ms_p50"] > 0
