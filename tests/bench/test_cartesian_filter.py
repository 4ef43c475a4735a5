"""The Cartesian benchmark's filter, on the MBM Panda: an independent IK path along a line, and
the reason a move is infeasible (its start, the line's reach, the arm's clearance)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from cartesian_filter import LineIk, infeasible_reason
from mbm_check import SceneChecker, panda_description
from mbm_problems import DEFAULT_DATA

pytestmark = pytest.mark.skipif(
    not (DEFAULT_DATA / "robot" / "panda.urdf").is_file(), reason=f"no MBM data at {DEFAULT_DATA}"
)

READY = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


@pytest.fixture(scope="module")
def ik() -> LineIk:
    return LineIk(SceneChecker(panda_description(DEFAULT_DATA / "robot")), "panda_hand")


def test_the_ik_path_keeps_the_hand_on_its_line(ik: LineIk) -> None:
    ik.checker.set_scene([])
    origin = ik.pose(READY)
    shift = 0.1 * origin.rotation[:, 2]
    states = ik.along(READY, shift)
    assert states is not None and len(states) >= 11
    for state in states:
        pose = ik.pose(state)
        offset = pose.translation - origin.translation
        along = np.dot(offset, shift) / np.dot(shift, shift)
        assert np.linalg.norm(offset - along * shift) < 1e-4 and -1e-6 <= along <= 1 + 1e-6
        assert np.linalg.norm(pin.log3(origin.rotation.T @ pose.rotation)) < 1e-3
    assert np.all(states >= ik.checker.lower) and np.all(states <= ik.checker.upper)
    assert infeasible_reason(ik, READY, shift) == ""


def test_a_line_out_of_reach_has_no_ik_path(ik: LineIk) -> None:
    ik.checker.set_scene([])
    assert infeasible_reason(ik, READY, np.array([2.0, 0.0, 0.0])) == "no_ik_along_line"


def test_an_object_by_the_arm_not_the_hand_blocks_the_move(ik: LineIk) -> None:
    origin = ik.pose(READY)
    shift = 0.1 * origin.rotation[:, 2]
    # beside link 5, clear at the start: the elbow lowers into it as the hand moves down
    post = {"id": "post", "type": "box", "size": [0.04, 0.04, 0.04],
            "pose": {"position": [0.119, 0.06, 0.597]}}  # fmt: skip
    ik.checker.set_scene([post])
    states = ik.along(READY, shift)
    assert states is not None and ik.checker.is_free(READY)
    assert set(ik.checker.check_path(states).scene_pairs) == {"panda_link5–post"}
    assert infeasible_reason(ik, READY, shift) == "arm_blocked"
    ik.checker.set_scene([{**post, "pose": {"position": origin.translation.tolist()}}])
    assert infeasible_reason(ik, READY, shift) == "start_in_collision"
