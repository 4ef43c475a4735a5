"""Validation memo: skipped work is only ever work already certified; never an unsafe answer.

The robot is a 1 m rod swinging about z (one joint), the obstacles thin plates standing along
the radius; a key path is a list of joint angles. Every verdict is checked against the real
certified validator and, where it says "valid", against an independent dense check.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np
import pytest

from tests.robots import ROD_URDF
from trajcache.cache.index import Match
from trajcache.cache.memo import (
    MemoScope,
    MemoUse,
    ValidationMemo,
    proved_first,
    validate_with_memo,
)
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene, SceneObject
from trajcache.geometry.validation.certify import CertifierOptions
from trajcache.geometry.validation.validator import (
    Resolution,
    TrajectoryValidator,
    ValidationResult,
    ValidationStatus,
    interpolate,
)

PATH = np.array([[0.0], [0.4], [0.9], [1.4], [1.8]])  # segments 0–0.4, 0.4–0.9, 0.9–1.4, 1.4–1.8


@pytest.fixture(scope="module")
def swing() -> RobotModel:
    return load_robot_model(ROD_URDF)


def plates(*angles: float) -> Scene:
    """Thin plates along the radius at `angles` (rad), 0.6–0.9 m out; the hash names them."""
    objects = []
    for k, angle in enumerate(angles):
        c, s = np.cos(angle), np.sin(angle)
        pose = np.eye(4)
        pose[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
        pose[:3, 3] = [0.75 * c, 0.75 * s, 0.5]
        objects.append(SceneObject(f"plate{k}", Shape(ShapeKind.BOX, (0.3, 0.004, 0.2)), pose))
    return Scene(tuple(objects), {}, "plates:" + ",".join(f"{a:.9f}" for a in angles))


class Counted:
    """The real validator's `validate`, recording the key states of every call."""

    def __init__(self, validator: TrajectoryValidator) -> None:
        self.validator = validator
        self.calls: list[np.ndarray] = []

    def __call__(self, states: np.ndarray) -> ValidationResult:
        self.calls.append(np.array(states))
        return self.validator.validate(states)


def scope_of(scene: Scene, model: RobotModel) -> MemoScope:
    return MemoScope(model.model_id, scene.hash, (Resolution(), True))


def run(
    states: np.ndarray, fn: Counted, memo: ValidationMemo, scope: MemoScope | None
) -> tuple[ValidationResult, MemoUse]:
    return validate_with_memo(states, validate_fn=fn, memo=memo, scope=scope)


def dense_collides(validator: TrajectoryValidator, key: np.ndarray, factor: int = 20) -> bool:
    """An independent check: 20× finer samples, no padding."""
    step = Resolution().joint_rad / factor
    fine = interpolate(key, validator.model, Resolution(0.04 / factor, 0.04 / factor, step))
    return bool(validator.checker.check(fine).first_collision >= 0)


def with_ends(start: float, goal: float) -> np.ndarray:
    path = PATH.copy()
    path[0, 0], path[-1, 0] = start, goal
    return path


def test_a_valid_path_is_remembered_and_an_exact_repeat_is_not_checked_again(
    swing: RobotModel,
) -> None:
    scene = plates(-1.0)
    fn, memo = Counted(TrajectoryValidator(swing, scene)), ValidationMemo()
    result, use = run(PATH, fn, memo, scope_of(scene, swing))
    assert result.valid and use is MemoUse.NONE and len(fn.calls) == 1
    again, use = run(PATH.copy(), fn, memo, scope_of(scene, swing))
    assert again.valid and use is MemoUse.WHOLE and len(fn.calls) == 1


def test_new_endpoints_validate_only_the_first_and_last_segments(swing: RobotModel) -> None:
    scene = plates(-1.0)
    fn, memo = Counted(TrajectoryValidator(swing, scene)), ValidationMemo()
    run(PATH, fn, memo, scope_of(scene, swing))
    result, use = run(with_ends(0.05, 1.75), fn, memo, scope_of(scene, swing))
    assert result.valid and use is MemoUse.ENDS
    assert [c[:, 0].tolist() for c in fn.calls[1:]] == [[0.05, 0.4], [1.4, 1.75]]
    full = TrajectoryValidator(swing, scene).validate(with_ends(0.05, 1.75))
    assert 0 < result.samples < full.samples  # less work than validating everything


@pytest.mark.parametrize(("start", "goal", "plate"), [(-0.3, 1.8, -0.15), (0.0, 2.2, 2.0)])
def test_a_new_end_segment_that_collides_is_caught(
    swing: RobotModel, start: float, goal: float, plate: float
) -> None:
    """The plate lies only in the new first (or last) segment, outside the remembered path."""
    scene = plates(plate)
    fn, memo = Counted(TrajectoryValidator(swing, scene)), ValidationMemo()
    assert run(PATH, fn, memo, scope_of(scene, swing))[0].valid
    result, use = run(with_ends(start, goal), fn, memo, scope_of(scene, swing))
    assert use is MemoUse.ENDS
    assert result.status is ValidationStatus.COLLISION
    assert "plate0" in result.message
    assert not memo.known_valid(scope_of(scene, swing), with_ends(start, goal))


def test_a_changed_scene_is_a_new_scope_and_the_whole_path_is_validated(
    swing: RobotModel,
) -> None:
    free, blocked = plates(-1.0), plates(-1.0, 1.15)  # 1.15 rad: inside segment 0.9–1.4
    memo = ValidationMemo()
    assert run(PATH, Counted(TrajectoryValidator(swing, free)), memo, scope_of(free, swing))[
        0
    ].valid
    fn = Counted(TrajectoryValidator(swing, blocked))
    result, use = run(PATH, fn, memo, scope_of(blocked, swing))
    assert use is MemoUse.NONE and len(fn.calls) == 1 and np.array_equal(fn.calls[0], PATH)
    assert result.status is ValidationStatus.COLLISION


def test_other_validator_settings_are_a_new_scope(swing: RobotModel) -> None:
    scene = plates(-1.0)
    memo = ValidationMemo()
    run(PATH, Counted(TrajectoryValidator(swing, scene)), memo, scope_of(scene, swing))
    coarse = MemoScope(swing.model_id, scene.hash, (Resolution(joint_rad=0.1), True))
    assert not memo.known_valid(coarse, PATH)
    assert not memo.known_valid(MemoScope("other-model", scene.hash, (Resolution(), True)), PATH)


def test_the_scope_is_the_validators_model_scene_and_settings_key(swing: RobotModel) -> None:
    """`MemoScope.of` follows every input of a verdict; a scene without a hash has no scope."""
    scene = plates(-1.0)
    base = MemoScope.of(TrajectoryValidator(swing, scene))
    assert base is not None and base == MemoScope.of(TrajectoryValidator(swing, scene))
    other = load_robot_model(ROD_URDF.replace('name="rod"', 'name="rod2"', 1))
    scopes = {
        base,
        MemoScope.of(TrajectoryValidator(swing, scene, resolution=Resolution(joint_rad=0.01))),
        MemoScope.of(TrajectoryValidator(swing, scene, certified=False)),
        MemoScope.of(TrajectoryValidator(swing, scene, certifier=CertifierOptions(min_pad=1e-3))),
        MemoScope.of(TrajectoryValidator(other, scene)),
        MemoScope.of(TrajectoryValidator(swing, plates(-1.0, 1.15))),
    }
    assert len(scopes) == 6
    unhashed = Scene(scene.objects, {}, "")
    assert MemoScope.of(TrajectoryValidator(swing, unhashed)) is None


def test_a_path_that_fails_is_never_remembered(swing: RobotModel) -> None:
    scene = plates(1.15)
    fn, memo = Counted(TrajectoryValidator(swing, scene)), ValidationMemo()
    for _ in range(2):
        result, use = run(PATH, fn, memo, scope_of(scene, swing))
        assert result.status is ValidationStatus.COLLISION and use is MemoUse.NONE
    assert len(memo) == 0 and len(fn.calls) == 2
    assert not memo.known_valid(scope_of(scene, swing), PATH[1:-1])


def test_a_changed_interior_is_validated_in_full(swing: RobotModel) -> None:
    """Re-anchoring moves interior states: any change of any value is a different entry."""
    scene = plates(1.15)
    blocked = TrajectoryValidator(swing, scene)
    memo = ValidationMemo()
    detour = np.array([[0.0], [0.4], [0.9], [1.0], [0.9], [0.4], [0.0]])
    assert run(detour, Counted(blocked), memo, scope_of(scene, swing))[0].valid
    moved = detour.copy()
    moved[1:-1] += 0.3  # the interior now reaches 1.3 rad, through the plate
    fn = Counted(blocked)
    result, use = run(moved, fn, memo, scope_of(scene, swing))
    assert use is MemoUse.NONE and np.array_equal(fn.calls[0], moved)
    assert result.status is ValidationStatus.COLLISION
    nudged = detour.copy()
    nudged[3, 0] += 1e-12
    assert run(nudged, Counted(blocked), memo, scope_of(scene, swing))[1] is MemoUse.NONE


def test_short_paths_and_unhashed_scenes_are_validated_in_full(swing: RobotModel) -> None:
    scene = plates(-1.0)
    fn, memo = Counted(TrajectoryValidator(swing, scene)), ValidationMemo()
    run(np.array([[0.0], [0.5], [1.0]]), fn, memo, scope_of(scene, swing))
    # a 3-state path has no segment that endpoint substitution leaves alone
    _, use = run(np.array([[0.1], [0.5], [0.9]]), fn, memo, scope_of(scene, swing))
    assert use is MemoUse.NONE and fn.calls[-1][:, 0].tolist() == [0.1, 0.5, 0.9]
    fresh = ValidationMemo()
    for n in (3, 4):
        result, use = run(PATH, fn, fresh, None)
        assert result.valid and use is MemoUse.NONE and len(fn.calls) == n
    assert len(fresh) == 0


def test_random_paths_never_come_back_valid_when_they_collide(swing: RobotModel) -> None:
    """Seeded search: remembered interiors with random new endpoints, checked densely."""
    rng = np.random.default_rng(7)
    uses: dict[tuple[MemoUse, bool], int] = {}
    for _ in range(25):
        scene = plates(*rng.uniform(-2.8, 2.8, size=2))
        validator = TrajectoryValidator(swing, scene)
        memo, scope = ValidationMemo(), scope_of(scene, swing)
        interior = np.sort(rng.uniform(-1.5, 1.5, size=(int(rng.integers(2, 5)), 1)), axis=0)
        for _ in range(6):
            path = np.vstack(
                [rng.uniform(-2.5, 2.5, (1, 1)), interior, rng.uniform(-2.5, 2.5, (1, 1))]
            )
            result, use = run(path, Counted(validator), memo, scope)
            truth = dense_collides(validator, path)
            assert not (result.valid and truth), (path.ravel(), scene.hash)
            key = (use, result.valid)
            uses[key] = uses.get(key, 0) + 1
    # the search really exercised the memo, both ways
    assert uses.get((MemoUse.ENDS, True), 0) > 20
    assert uses.get((MemoUse.ENDS, False), 0) > 10


def test_the_memo_is_a_bounded_lru() -> None:
    memo = ValidationMemo(capacity=3)
    scope = MemoScope("m", "s", ())
    paths = [np.array([[float(i)], [1.0]]) for i in range(4)]
    for p in paths[:3]:
        memo.remember(scope, p)
    assert memo.known_valid(scope, paths[0])  # now the most recently used
    memo.remember(scope, paths[3])
    assert len(memo) == 3
    assert not memo.known_valid(scope, paths[1])  # the least recently used went
    assert all(memo.known_valid(scope, p) for p in (paths[0], paths[2], paths[3]))
    with pytest.raises(ValueError, match="capacity"):
        ValidationMemo(capacity=0)


def test_the_memo_is_safe_to_share_between_threads() -> None:
    memo = ValidationMemo(capacity=50)
    scope = MemoScope("m", "s", ())
    errors: list[BaseException] = []

    def worker(k: int) -> Callable[[], None]:
        def body() -> None:
            try:
                for i in range(300):
                    path = np.array([[float(k)], [float(i)]])
                    memo.remember(scope, path)
                    memo.known_valid(scope, path)
            except BaseException as exc:  # surfaced below
                errors.append(exc)

        return body

    threads = [threading.Thread(target=worker(k)) for k in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors and len(memo) == 50


@pytest.mark.parametrize("seed", range(6))
def test_segments_in_one_pass_give_the_verdict_of_each_segment_alone(
    swing: RobotModel, seed: int
) -> None:
    """`validate_segments` lays the pieces end to end; its junctions are never motions: a plate
    that only the jump from one piece to the next would cross is not found, and a plate in any
    listed segment is."""
    rng = np.random.default_rng(seed)
    validator = TrajectoryValidator(swing, plates(*rng.uniform(-3.0, 3.0, 2)))
    for _ in range(20):
        path = np.sort(rng.uniform(-3.0, 3.0, (6, 1)), axis=0) * rng.choice([-1.0, 1.0])
        listed = sorted(rng.choice(5, size=int(rng.integers(1, 4)), replace=False).tolist())
        alone = [validator.validate(path[i : i + 2]) for i in listed]
        together = validator.validate_segments(path, listed)
        first = next((r for r in alone if not r.valid), None)
        assert together.status is (first.status if first else ValidationStatus.VALID)
        if first is not None:
            assert together.state is not None and first.state is not None
            assert np.allclose(together.state, first.state)


def test_a_plate_between_two_pieces_is_not_a_finding(swing: RobotModel) -> None:
    validator = TrajectoryValidator(swing, plates(0.65))
    path = np.array([[0.0], [0.3], [1.0], [1.3]])  # the plate lies in segment 1 only
    assert not validator.validate(path).valid
    assert validator.validate_segments(path, [0, 2]).valid
    assert validator.validate_segments(path, [0, 1]).status is ValidationStatus.COLLISION


def test_candidates_proved_in_the_scene_are_tried_first(swing: RobotModel) -> None:
    """Of several candidates, those whose interior (as played) passed certified validation in
    this scope go first, each group in its order; a reversed match is looked up reversed, and
    another scope's proof does not count."""
    scene, memo = plates(-1.0), ValidationMemo()
    scope = scope_of(scene, swing)
    other = np.array([[0.0], [0.3], [1.0], [1.8]])
    stored = {1: other, 2: PATH, 3: PATH[::-1].copy(), 4: PATH}
    matches = [Match(i, i == 3, 0.0, 0.0, 0.01 * i) for i in (1, 2, 3, 4)]
    assert proved_first(memo, scope, matches, stored) == matches  # nothing proved yet
    result, _ = run(PATH, Counted(TrajectoryValidator(swing, scene)), memo, scope)
    assert result.valid  # PATH's interior is remembered in this scope
    ordered = proved_first(memo, scope, matches, stored)
    assert [m.trajectory_id for m in ordered] == [2, 3, 4, 1]  # 3 reversed: played as PATH
    elsewhere = scope_of(plates(1.0), swing)
    assert proved_first(memo, elsewhere, matches, stored) == matches
