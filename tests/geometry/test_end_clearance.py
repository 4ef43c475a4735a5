"""End clearances: an adapted end segment proved from the clearance along the stored one, on the
Panda as shipped (meshes, SRDF), against a 20× denser check; the audit; the store's keys."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from trajcache.cache.end_clearances import EndClearances
from trajcache.cache.memo import MemoScope
from trajcache.geometry.collision.bodies import Posed
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import SceneObject, make_scene
from trajcache.geometry.validation.certificates import CertificateDisagreement, moved_by
from trajcache.geometry.validation.end_clearance import (
    CAP,
    SegmentClearance,
    measure_clearance,
    motion_tables,
    open_intervals,
    validate_ends,
)
from trajcache.geometry.validation.validator import Resolution, TrajectoryValidator, interpolate
from trajcache.reference.example_robots import ROBOTS

FINE = Resolution(0.04 / 20, 0.04 / 20, Resolution().joint_rad / 20)


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    robot = ROBOTS["panda"]
    return load_robot_model(robot.urdf, files=robot.files(), srdf=robot.srdf, group="arm")


def _dense_free(validator: TrajectoryValidator, segment: FloatArray) -> bool:
    fine = interpolate(segment, validator.model, FINE)
    return bool(validator.checker.check(fine).first_collision < 0)


def _near(panda: RobotModel, state: FloatArray, rng: np.random.Generator, k: int) -> SceneObject:
    """A box or a thin plate a few centimetres from a random link at `state`."""
    frames = link_transforms(panda, state)[0]
    pose = np.eye(4)
    angle = rng.uniform(-math.pi, math.pi)
    pose[:3, :3] = [[math.cos(angle), -math.sin(angle), 0], [math.sin(angle), math.cos(angle), 0],
                    [0, 0, 1]]  # fmt: skip
    pose[:3, 3] = frames[rng.integers(1, len(frames)), :3, 3] + rng.normal(0.0, 0.1, 3)
    size = (0.004, 0.3, 0.3) if k == 0 else tuple(rng.uniform(0.02, 0.15, 3))  # a thin plate
    return SceneObject(f"thing_{k}", Shape(ShapeKind.BOX, size), pose)


def _stored_segment(
    panda: RobotModel, rng: np.random.Generator
) -> tuple[TrajectoryValidator, FloatArray]:
    """A scene of objects close to a segment that its validator certifies, and the segment."""
    while True:
        start = rng.uniform(panda.lower, panda.upper)
        goal = np.clip(start + rng.normal(0.0, 0.4, panda.dof), panda.lower, panda.upper)
        objects = [_near(panda, start if k % 2 else goal, rng, k) for k in range(4)]
        validator = TrajectoryValidator(panda, make_scene(objects))
        segment = np.stack([start, goal])
        ends_free = validator.checker.check(segment).first_collision < 0  # cheap, first
        if ends_free and validator.validate(segment).valid:
            return validator, segment


@dataclass(frozen=True)
class _Known:
    stored: FloatArray
    clearance: SegmentClearance

    def get(self, segment: FloatArray) -> SegmentClearance | None:
        return self.clearance if np.array_equal(segment, self.stored) else None


def test_what_a_clearance_proves_a_denser_check_finds_free(panda: RobotModel) -> None:
    rng = np.random.default_rng(5)
    outcomes = {"proved": 0, "shortened": 0, "colliding": 0, "free": 0}
    for _ in range(16):
        validator, stored = _stored_segment(panda, rng)
        clearance = measure_clearance(validator, stored)
        assert clearance.scene.shape[0] == clearance.pairs.shape[0] == len(clearance.fractions) - 1
        assert (clearance.scene <= CAP).all() and (clearance.pairs <= CAP).all()
        known = _Known(stored, clearance)
        for size in (0.005, 0.02, 0.08, 0.25):
            for end in (0, 1, 2):  # a new first state, a new last state, both
                new = stored.copy()
                for k in (0, 1) if end == 2 else (end,):
                    moved = stored[k] + rng.uniform(-size, size, panda.dof)
                    new[k] = np.clip(moved, panda.lower, panda.upper)
                span = clearance.unproved(validator.checker, stored, new)
                verdict = validate_ends(validator, new, [0], stored=stored, known=known.get)
                free = _dense_free(validator, new)
                if span is None:
                    outcomes["proved"] += 1
                    assert free, "a clearance proved a segment the dense check finds colliding"
                elif span != (0.0, 1.0):
                    outcomes["shortened"] += 1
                if verdict.valid:
                    assert free, "a shortened validation passed a colliding segment"
                outcomes["free" if free else "colliding"] += 1
    assert outcomes["proved"] > 2 and outcomes["shortened"] > 10, outcomes
    assert outcomes["colliding"] > 3, outcomes  # the moves reach the objects sometimes


def test_the_compiled_span_is_the_motion_test_of_the_module_docstring() -> None:
    rng = np.random.default_rng(11)
    spans = set()
    for n_pairs in (0, 5):
        for _ in range(300):
            k, e, d = int(rng.integers(2, 9)), 4, 3
            fractions = np.linspace(0.0, 1.0, k)
            scene = rng.uniform(0.0, 0.2, (k - 1, e))
            pairs = rng.uniform(0.0, 0.2, (k - 1, n_pairs))
            d0, d1 = rng.normal(0, 0.05, d) * (rng.random() < 0.7), rng.normal(0, 0.05, d)
            element, pair = rng.uniform(0, 1, (e, d)), rng.uniform(0, 1, (n_pairs, d))
            apart = np.abs(d0 + fractions[:, None] * (d1 - d0))  # in numpy, as the docstring
            sigma = np.maximum(apart[:-1], apart[1:])
            ok = (scene > sigma @ element.T).all(axis=1) & (pairs > sigma @ pair.T).all(axis=1)
            bad = np.flatnonzero(~ok)
            expected = (int(bad[0]), int(bad[-1])) if len(bad) else (-1, -1)
            got = open_intervals(fractions, scene, pairs, d0, d1, element, pair)
            assert got == expected
            spans.add("none" if got[0] < 0 else "all" if got == (0, k - 2) else "part")
    assert spans == {"none", "all", "part"}


def test_a_clearance_is_a_lower_bound_of_the_dense_distance(panda: RobotModel) -> None:
    """No element comes closer to the scene, at any dense state, than its interval's bound."""
    rng = np.random.default_rng(8)
    denser = Resolution(0.02, 0.02, Resolution().joint_rad / 3)
    for _ in range(4):
        validator, stored = _stored_segment(panda, rng)
        clearance = measure_clearance(validator, stored)
        fine = interpolate(stored, panda, denser)
        fractions = np.linspace(0.0, 1.0, len(fine))
        checker = validator.checker
        posed = Posed.build(checker.robot, fine)
        e, m = len(checker.robot.radius), len(checker.scene.ids)
        rows = np.array([(k, i, o) for k in range(len(fine)) for i in range(e) for o in range(m)])
        exact = checker.narrow.scene_exact(posed, rows).reshape(len(fine), e, m).min(axis=2)
        interval = np.minimum(
            np.searchsorted(clearance.fractions, fractions, side="right") - 1,
            len(clearance.fractions) - 2,
        )
        assert (clearance.scene[interval] <= exact + 1e-9).all()


def _points(panda: RobotModel, state: FloatArray) -> list[FloatArray]:
    """Every element's mesh vertices (none for a primitive) in the world at `state`."""
    frames = link_transforms(panda, state)[0]
    out = []
    for element in panda.elements:
        local = element.shape.vertices
        local = np.zeros((0, 3)) if local is None else local
        pose = frames[element.link] @ element.origin
        out.append(local @ pose[:3, :3].T + pose[:3, 3])
    return out


def test_no_point_moves_further_than_themotion_tables_allow(panda: RobotModel) -> None:
    """W bounds how far any point of an element moves, V how much any two points of a checked
    pair move relative to each other, for a change of state by δ, anywhere in the limits."""
    checker = CollisionChecker(panda, make_scene([]))
    element, pair = motion_tables(checker.robot)
    robot = checker.robot
    rng = np.random.default_rng(6)
    tightest = 0.0
    for _ in range(60):
        q = rng.uniform(panda.lower, panda.upper)
        delta = rng.uniform(-0.1, 0.1, panda.dof)
        before, after = _points(panda, q), _points(panda, q + delta)
        moved = [np.linalg.norm(a - b, axis=1) for a, b in zip(after, before, strict=True)]
        for e, bound in enumerate(element @ np.abs(delta)):
            if len(moved[e]):
                assert moved[e].max() <= bound + 1e-9
                tightest = max(tightest, moved[e].max() / bound)
        for p, bound in enumerate(pair @ np.abs(delta)):
            i, j = robot.pair_i[p], robot.pair_j[p]
            a, b = before[i][::7], before[j][::7]
            a2, b2 = after[i][::7], after[j][::7]
            if not (len(a) and len(b)):
                continue
            change = np.abs(
                np.linalg.norm(a2[:, None] - b2[None], axis=2)
                - np.linalg.norm(a[:, None] - b[None], axis=2)
            )
            assert change.max() <= bound + 1e-9
    assert tightest > 0.3  # the bounds are not vacuous: some point moves a third of its bound


def test_a_planar_base_is_not_covered() -> None:
    from trajcache.reference.robot import reference_model

    model = reference_model()
    validator = TrajectoryValidator(model, make_scene([]))
    stored = np.stack([model.lower * 0.0, model.lower * 0.0 + 0.1])
    clearance = measure_clearance(validator, stored)
    assert clearance.unproved(validator.checker, stored, stored) == (0.0, 1.0)


def test_the_audit_raises_when_a_clearance_is_wrong(panda: RobotModel) -> None:
    rng = np.random.default_rng(2)
    validator, stored = _stored_segment(panda, rng)
    hand = link_transforms(panda, stored[0])[0][panda.link_names.index("panda_hand")]
    block = SceneObject("block", Shape(ShapeKind.BOX, (0.08, 0.08, 0.08)), hand)
    blocked = TrajectoryValidator(panda, make_scene([block]))
    fine = measure_clearance(validator, stored)
    wrong = SegmentClearance(fine.fractions, np.full_like(fine.scene, CAP), fine.pairs)
    path = np.vstack([stored, stored[::-1]])  # four states: segments 0 and 2 are its ends
    known = {stored.tobytes(): wrong, stored[::-1].tobytes(): wrong.reversed()}
    assert validate_ends(
        blocked, path, [0, 2], stored=path, known=lambda s: known.get(s.tobytes())
    ).valid  # the wrong clearance proves it
    with pytest.raises(CertificateDisagreement):
        validate_ends(
            blocked, path, [0, 2], stored=path, known=lambda s: known.get(s.tobytes()), audit=True
        )
    assert not validate_ends(blocked, path, [0, 2], stored=path, known=lambda s: None).valid


def _box(name: str, x: float, size: float = 0.1) -> SceneObject:
    pose = np.eye(4)
    pose[0, 3] = x
    return SceneObject(name, Shape(ShapeKind.BOX, (size, size, size)), pose)


def test_the_store_keys_by_variant_and_segment_and_follows_the_scene(panda: RobotModel) -> None:
    store = EndClearances()
    scene = make_scene([_box("a", 1.0), _box("b", -1.0)])
    scope = MemoScope(panda.model_id, scene.hash, ("settings",))
    segment = np.array([np.zeros(panda.dof), np.full(panda.dof, 0.3)])
    clearance = SegmentClearance(
        np.array([0.0, 0.5, 1.0]), np.array([[0.05], [0.06]]), np.array([[0.03], [0.04]])
    )
    store.put(scope, segment, clearance, scene)
    assert store.get(scope, segment, scene) is clearance
    other_variant = MemoScope("another variant", scene.hash, ("settings",))
    assert store.get(other_variant, segment, scene) is None
    assert store.get(scope, segment + 1e-12, scene) is None  # the exact bits only
    back = store.get(scope, segment[::-1], scene)
    assert back is not None
    assert np.array_equal(back.fractions, [0.0, 0.5, 1.0])
    assert np.array_equal(back.scene, [[0.06], [0.05]])
    assert np.array_equal(back.pairs, [[0.04], [0.03]])
    # objects moved by 1 and 2 cm: the scene's part loses the larger move, the pairs' none
    moved = make_scene([_box("a", 1.01), _box("b", -1.02)])
    less = store.get(MemoScope(panda.model_id, moved.hash, ("settings",)), segment, moved)
    assert less is not None
    assert np.allclose(less.scene, [[0.03], [0.04]]) and np.array_equal(less.pairs, clearance.pairs)
    for changed in (
        make_scene([_box("a", 1.0), _box("b", -1.0), _box("c", 3.0)]),  # a new object
        make_scene([_box("a", 1.0), _box("b", -1.0, size=0.2)]),  # a resized one
        make_scene([_box("a", 1.0), _box("b", -1.0)], allowed=[("b", "panda_hand")]),
    ):
        there = MemoScope(panda.model_id, changed.hash, ("settings",))
        assert store.get(there, segment, changed) is None
    fewer = make_scene([_box("a", 1.0)])  # an object gone: what was proved still holds
    assert store.get(MemoScope(panda.model_id, fewer.hash, ("settings",)), segment, fewer)
    small = EndClearances(max_bytes=2048)
    for k in range(10):
        small.put(scope, segment + k, clearance, scene)
    assert 0 < len(small) < 10  # bounded in bytes


def test_a_segment_is_claimed_for_measuring_once_per_scene(panda: RobotModel) -> None:
    store = EndClearances()
    scope = MemoScope(panda.model_id, "scene-1", ("settings",))
    segment = np.array([np.zeros(panda.dof), np.full(panda.dof, 0.3)])
    assert store.claim(scope, segment)
    assert not store.claim(scope, segment) and not store.claim(scope, segment[::-1])
    assert store.claim(MemoScope(panda.model_id, "scene-2", ("settings",)), segment)
    assert store.claim(scope, segment + 0.1)  # another segment
    store.release(scope, segment)
    assert store.claim(scope, segment)  # measured, or given up: it may be queued again


def test_a_clearance_carried_to_moved_objects_proves_only_free_segments(
    panda: RobotModel,
) -> None:
    rng = np.random.default_rng(12)
    outcomes = {"proved": 0, "colliding": 0}
    for _ in range(24):
        validator, stored = _stored_segment(panda, rng)
        scene = validator.checker.scene.scene
        store = EndClearances()
        scope = MemoScope(panda.model_id, scene.hash, ("settings",))
        store.put(scope, stored, measure_clearance(validator, stored), scene)
        for _ in range(4):
            objects = []
            for obj in scene.objects:
                pose = obj.pose.copy()
                pose[:3, 3] += rng.uniform(-0.003, 0.003, 3)
                objects.append(SceneObject(obj.id, obj.shape, pose))
            moved = make_scene(objects)
            there = TrajectoryValidator(panda, moved)
            carried = store.get(MemoScope(panda.model_id, moved.hash, ("settings",)), stored, moved)
            assert carried is not None
            new = stored.copy()
            new[1] = np.clip(
                stored[1] + rng.uniform(-0.02, 0.02, panda.dof), panda.lower, panda.upper
            )
            free = _dense_free(there, new)
            outcomes["colliding"] += not free
            if carried.unproved(there.checker, stored, new) is None:
                outcomes["proved"] += 1
                assert free, "a carried clearance proved a segment the dense check finds colliding"
    assert outcomes["proved"] > 2 and outcomes["colliding"] > 0, outcomes


def test_no_point_of_a_moved_body_moves_further_than_moved_by() -> None:
    rng = np.random.default_rng(9)
    tightest = 0.0
    for _ in range(200):
        poses = []
        for _ in range(2):
            pose = np.eye(4)
            axis = rng.normal(size=3)
            pose[:3, :3] = _rotation(axis / np.linalg.norm(axis), rng.uniform(-0.5, 0.5))
            pose[:3, 3] = rng.normal(0.0, 0.05, 3)
            poses.append(pose)
        radius = float(rng.uniform(0.01, 1.0))
        points = rng.normal(size=(64, 3))
        points *= radius / np.linalg.norm(points, axis=1, keepdims=True)
        before = points @ poses[0][:3, :3].T + poses[0][:3, 3]
        after = points @ poses[1][:3, :3].T + poses[1][:3, 3]
        bound = moved_by(poses[0], poses[1], radius)
        moved = float(np.linalg.norm(after - before, axis=1).max())
        assert moved <= bound + 1e-12
        tightest = max(tightest, moved / bound)
    assert tightest > 0.9


def _rotation(axis: FloatArray, angle: float) -> FloatArray:
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.asarray(np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k)


def test_a_clearance_measured_for_other_elements_or_pairs_proves_nothing(
    panda: RobotModel,
) -> None:
    checker = CollisionChecker(panda, make_scene([_box("a", 1.0)]))
    elements, pairs = len(checker.robot.radius), len(checker.robot.pair_i)
    segment = np.array([np.zeros(panda.dof), np.full(panda.dof, 0.1)])
    ends = np.array([0.0, 1.0])

    def clearance(e: int, p: int) -> SegmentClearance:
        return SegmentClearance(ends, np.full((1, e), 1.0), np.full((1, p), 1.0))

    assert clearance(elements, pairs).unproved(checker, segment, segment) is None
    assert clearance(elements, 0).unproved(checker, segment, segment) is None  # no pairs kept
    assert clearance(elements + 1, pairs).unproved(checker, segment, segment) == (0.0, 1.0)
    assert clearance(elements, pairs + 1).unproved(checker, segment, segment) == (0.0, 1.0)
