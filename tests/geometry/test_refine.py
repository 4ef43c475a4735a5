"""Open segments cut into pieces before exact distances (`geometry/validation/refine.py`): the
pieces keep the segment's ends, a finding maps back to the same state, pieces are checked for the
open pairs alone and find what a check of every pair finds among them, and validators that cut
and that do not agree with each other and with a 20× denser check on the Panda."""

from __future__ import annotations

import numpy as np

from tests.geometry.test_compiled import _near_scene, panda  # noqa: F401 (a fixture)
from trajcache.geometry.collision.bodies import Posed
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.space import segment_deltas
from trajcache.geometry.validation.certify import CertifierOptions
from trajcache.geometry.validation.refine import certify_in_pieces, open_runs, pieces, restricted
from trajcache.geometry.validation.segments import Finding, OpenPairs, SegmentStatus
from trajcache.geometry.validation.validator import (
    Resolution,
    TrajectoryValidator,
    ValidationStatus,
    interpolate,
)


def _open(segments: list[int]) -> OpenPairs:
    rows = np.array([[s, 0, 0] for s in segments], dtype=np.int64).reshape(-1, 3)
    zeros = np.zeros(len(segments))
    return OpenPairs(True, rows, zeros, zeros, zeros + 1.0)


def test_open_segments_form_runs_in_order() -> None:
    groups = [_open([4, 1, 2, 2]), _open([7, 5])]
    assert open_runs(groups) == [(1, 2), (4, 5), (7, 7)]


def test_pieces_keep_the_segments_own_states_exactly() -> None:
    states = np.random.default_rng(0).normal(size=(5, 3))
    delta = np.diff(states, axis=0)
    cut = pieces(states, delta, (1, 2), 3)
    assert cut.shape == (7, 3)
    for i, k in ((1, 0), (2, 3), (3, 6)):
        assert np.array_equal(cut[k], states[i])
    assert np.allclose(cut[1], states[1] + delta[1] / 3)


def test_a_finding_in_a_piece_names_the_same_state_in_its_segment() -> None:
    states = np.arange(12, dtype=float).reshape(6, 2)
    delta = np.diff(states, axis=0)

    def certify(cut: np.ndarray) -> Finding:  # the collision is in the 5th piece, halfway
        assert len(cut) == 3 * 2 + 1
        return Finding(SegmentStatus.COLLISION, 4, 0.5, subdivisions=2)

    found = certify_in_pieces(certify, states, delta, [_open([2, 3])], 3)
    assert found.status is SegmentStatus.COLLISION and found.subdivisions == 2
    assert found.segment == 3 and np.isclose(found.at, 1.5 / 3)
    piece_state = pieces(states, delta, (2, 3), 3)[4] + 0.5 * delta[3] / 3
    assert np.allclose(states[found.segment] + found.at * delta[found.segment], piece_state)


def test_cut_and_uncut_agree_with_each_other_and_a_denser_check(panda: RobotModel) -> None:  # noqa: F811
    rng = np.random.default_rng(23)
    fine = Resolution(0.04 / 20, 0.04 / 20, Resolution().joint_rad / 20)
    seen = {"valid": 0, "collision": 0}
    for _ in range(12):
        scene, start = _near_scene(panda, rng)
        cut = TrajectoryValidator(panda, scene, certifier=CertifierOptions(pieces=3))
        whole = TrajectoryValidator(panda, scene, certifier=CertifierOptions(pieces=1))
        for _ in range(3):
            goal = np.clip(start + rng.normal(0.0, 0.4, panda.dof), panda.lower, panda.upper)
            key = np.stack([start, goal])
            a, b = cut.validate(key), whole.validate(key)
            dense = cut.checker.check(interpolate(key, panda, fine)).first_collision >= 0
            if a.valid:
                assert not dense, "certified a motion the dense check finds in collision"
            if ValidationStatus.TOO_CLOSE not in (a.status, b.status):
                assert a.status is b.status
            if a.status is ValidationStatus.COLLISION:
                assert a.state is not None and cut.checker.state_contacts(a.state)
                seen["collision"] += 1
            seen["valid"] += a.valid
    assert seen["valid"] > 5 and seen["collision"] > 5, seen


def test_pieces_check_only_the_open_pairs() -> None:
    scene = OpenPairs(True, np.array([[0, 1, 2], [3, 0, 1]]), *np.zeros((3, 2)))
    robot = OpenPairs(False, np.array([[0, 4], [2, 1], [5, 4]]), *np.zeros((3, 3)))
    pairs = (np.arange(6), np.arange(6) + 10, np.eye(6, 2), np.arange(12.0).reshape(2, 6))
    allowed = np.zeros((2, 3), dtype=bool)
    allowed[0, 0] = True
    only, kept, ids = restricted([scene, robot], allowed, (2, 3), pairs)
    assert only.tolist() == [[True, False, True], [True, True, False]]
    assert ids.tolist() == [1, 4]
    assert kept[0].tolist() == [1, 4] and kept[1].tolist() == [11, 14]
    assert np.array_equal(kept[2], np.eye(6, 2)[[1, 4]])
    assert np.array_equal(kept[3], pairs[3][:, [1, 4]]) and kept[3].flags.c_contiguous
    none, _, _ = restricted([scene, robot], np.zeros((0, 0), dtype=bool), (2, 3), pairs)
    assert not none[0, 1] and none[0, 0] and not none[1, 2]


def test_restricted_levels_leave_what_the_full_levels_leave_among_those_pairs(
    panda: RobotModel,  # noqa: F811
) -> None:
    """The compiled levels of pieces, restricted to some pairs, leave open exactly the rows the
    unrestricted levels leave among those pairs: robot pairs named by their index among all."""
    rng = np.random.default_rng(5)
    checked = {"scene": 0, "robot": 0}
    for _ in range(6):
        scene, start = _near_scene(panda, rng)
        certifier = TrajectoryValidator(panda, scene).certifier
        goal = np.clip(start + rng.normal(0.0, 1.0, panda.dof), panda.lower, panda.upper)
        states = np.linspace(start, goal, 4)
        posed = Posed.build(certifier.robot, states)
        step = certifier.robot.motion.steps(segment_deltas(states, base=panda.base))
        full = certifier._compiled_levels(posed, step)
        keep = [g.take(rng.random(len(g.rows)) < 0.5) for g in full]  # some open pairs
        part = certifier._compiled_levels(posed, step, only=keep)
        for whole, kept, got in zip(full, keep, part, strict=True):
            columns = slice(1, None)
            named = {tuple(r) for r in kept.rows[:, columns].tolist()}
            among = [i for i, r in enumerate(whole.rows[:, columns].tolist()) if tuple(r) in named]
            assert got.rows.tolist() == whole.rows[among].tolist()
            assert np.array_equal(got.lower_a, whole.lower_a[among])
            assert np.array_equal(got.motion, whole.motion[among])
            checked["scene" if whole.scene else "robot"] += len(among)
    assert checked["scene"] > 5 and checked["robot"] > 5, checked
