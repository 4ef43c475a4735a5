"""bench/ik.py: its targets are reachable poses, its independent check catches a wrong state,
and a smoke run ends with the JSON line of figures."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from ik import cases, independent_error, targets, yourdfpy_robot

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "ik.py"


def test_the_independent_check_accepts_the_target_state_and_catches_another() -> None:
    case = cases()[1]  # the reference robot, on its planar base
    rng = np.random.default_rng(3)
    pose = targets(case, 1, rng)[0]
    reference = yourdfpy_robot(case)
    rng = np.random.default_rng(3)  # the same draw as `targets`
    state = case.seed.copy()
    arm = slice(case.model.arm_offset, case.model.dof)
    state[arm] = rng.uniform(case.model.lower[arm], case.model.upper[arm], (1, 7))[0]
    assert not independent_error(reference, case, state, pose)
    state[4] += 0.1
    assert independent_error(reference, case, state, pose)


def test_a_smoke_run_ends_with_its_figures() -> None:
    run = subprocess.run(
        [sys.executable, str(SCRIPT), "--poses", "5", "--solvers", "dls"],
        capture_output=True, text=True, check=True, cwd=SCRIPT.parent, timeout=300,
    )  # fmt: skip
    figures = json.loads(run.stdout.strip().splitlines()[-1])
    assert figures["success_rate"] == 1.0 and figures["pose_errors"] == 0
    assert set(figures["solvers"]) == {"panda/dls", "reference/dls"}
    assert figures["ms_median"] > 0
