"""bench/validation.py: the Panda row counts a safety failure, and the smoke run is clean."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dense_mesh import MeshChecker
from naive_fcl import NaiveChecker, PairChecker
from trajcache.geometry.collision.checker import Contact, ContactKind
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.validation.certify import CertifierOptions
from trajcache.geometry.validation.validator import (
    TrajectoryValidator,
    ValidationResult,
    ValidationStatus,
)
from validation_panda import PandaTally, SceneCheckers, panda_model, rejection_reason

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "validation.py"
# A slab through the Panda's upper arm whatever its joints: every state touches it.
SLAB = {"id": "slab_1", "type": "box", "size": [3.0, 3.0, 0.2],
        "pose": {"position": [0.0, 0.0, 0.5], "orientation": [0.0, 0.0, 0.0, 1.0]}}  # fmt: skip
HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
PATH = np.stack([HOME, HOME + 0.5])
PANDA_KEYS = ("panda_ratio", "panda_path_ms_p50", "panda_states_per_s", "panda_paths",
              "panda_conservative", "panda_mismatches")  # fmt: skip
REFERENCE_KEYS = ("naive_states_per_s", "validator_states_per_s", "ratio", "ratio_late",
                  "ratio_workload", "validator_ms_per_trajectory", "mismatches")  # fmt: skip


class AcceptsEverything:
    """A validator that would be a safety failure."""

    def validate(self, key: np.ndarray) -> ValidationResult:
        return ValidationResult(ValidationStatus.VALID, len(key), 0)


@pytest.fixture(scope="module")
def panda() -> tuple[RobotModel, MeshChecker]:
    return panda_model()


def _checkers(panda: tuple[RobotModel, MeshChecker], certified: Any) -> SceneCheckers:
    model, dense = panda
    dense.set_scene([SLAB])
    scene = parse_scene({"objects": [SLAB]})
    plain = TrajectoryValidator(model, scene, certified=False)
    numpy = TrajectoryValidator(model, scene, certifier=CertifierOptions(compiled=False))
    naive, pairs = NaiveChecker(model, scene), PairChecker(model, scene)
    return SceneCheckers(model, certified, plain, numpy, naive, pairs, dense)


def test_a_colliding_path_accepted_is_a_mismatch(panda: tuple[RobotModel, MeshChecker]) -> None:
    tally = PandaTally()
    _checkers(panda, AcceptsEverything()).measure("straight", PATH, 1, tally)
    assert tally.mismatches == 1 and tally.paths[0].status is ValidationStatus.VALID


def test_the_validator_rejects_it_and_nothing_is_conservative(
    panda: tuple[RobotModel, MeshChecker],
) -> None:
    model, _ = panda
    validator = TrajectoryValidator(model, parse_scene({"objects": [SLAB]}))
    tally = PandaTally()
    _checkers(panda, validator).measure("straight", PATH, 1, tally)
    assert tally.mismatches == 0 and not tally.conservative
    assert tally.paths[0].status is ValidationStatus.COLLISION
    assert tally.naive_disagreements == 0 and tally.dense_samples == 1  # stops at the first


def test_a_too_close_reason_names_the_kind_of_object_not_its_number(
    panda: tuple[RobotModel, MeshChecker],
) -> None:
    result = ValidationResult(
        ValidationStatus.TOO_CLOSE,
        2,
        0,
        contacts=[Contact("panda_hand", "cage_ring_1_7", ContactKind.SCENE)],
        message="the motion passes closer than can be certified (…) between samples 3 and 4",
    )
    reason = rejection_reason(result, panda[1])
    assert reason == "passes closer than can be certified: panda_hand near cage_ring"


@pytest.mark.slow
def test_smoke_run_has_the_panda_row_and_no_mismatch() -> None:
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "--smoke", "--panda-problems", "1"],
        capture_output=True,
        text=True,
        timeout=240,
        check=False,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "panda meshes" in done.stdout
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    for key in (*REFERENCE_KEYS, *PANDA_KEYS):
        assert key in summary, key
    assert summary["mismatches"] == 0 and summary["panda_mismatches"] == 0
    assert summary["panda_paths"] >= 4 and summary["panda_naive_disagreements"] == 0
    assert summary["panda_ratio"] > 0 and summary["panda_path_ms_p50"] > 0
    verdicts = summary["panda_verdicts"]
    assert sum(n for kind in verdicts.values() for n in kind.values()) == summary["panda_paths"]
