"""Batched collision checks: the same verdicts as a per-state FCL loop, pads, first collision."""

from __future__ import annotations

import fcl
import numpy as np
import pytest

from trajcache.geometry.collision.checker import (
    AMBIGUOUS,
    COLLIDING,
    FREE,
    CollisionChecker,
    ContactKind,
)
from trajcache.geometry.model.kinematics import element_transforms, link_transforms
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.reference.restroom import restroom_layout, restroom_scene
from trajcache.reference.robot import STOWED_ARM, reference_model


class PerStateFCL:
    """The obvious check: every element pose, then FCL's managers, one state at a time."""

    def __init__(self, model: RobotModel, scene: Scene) -> None:
        self.model = model
        geoms = [e.shape.to_fcl() for e in model.elements]
        self.objs = [fcl.CollisionObject(g, fcl.Transform()) for g in geoms]
        self.link_of = {id(g): e.link for g, e in zip(geoms, model.elements, strict=True)}
        self.robot = fcl.DynamicAABBTreeCollisionManager()
        self.robot.registerObjects(self.objs)
        self.robot.setup()
        self.world = fcl.DynamicAABBTreeCollisionManager()
        self.world.registerObjects(
            [
                fcl.CollisionObject(o.shape.to_fcl(), fcl.Transform(o.pose[:3, :3], o.pose[:3, 3]))
                for o in scene.objects
            ]
        )
        self.world.setup()

    def collides(self, state: FloatArray) -> bool:
        poses = element_transforms(self.model, link_transforms(self.model, state[None]))[0]
        for obj, pose in zip(self.objs, poses, strict=True):
            obj.setTransform(fcl.Transform(pose[:3, :3], pose[:3, 3]))
        self.robot.update()
        data = fcl.CollisionData(request=fcl.CollisionRequest())
        self.robot.collide(self.world, data, fcl.defaultCollisionCallback)
        if data.result.is_collision:
            return True
        request = fcl.CollisionRequest(num_max_contacts=100_000, enable_contact=True)
        data = fcl.CollisionData(request=request)
        self.robot.collide(data, fcl.defaultCollisionCallback)
        for contact in data.result.contacts:
            a, b = self.link_of[id(contact.o1)], self.link_of[id(contact.o2)]
            if a != b and (min(a, b), max(a, b)) not in self.model.allowed_pairs:
                return True
        return False


def _station_states(model: RobotModel, rng: np.random.Generator, count: int) -> FloatArray:
    stations = np.array([s.pose for s in restroom_layout().stations])
    base = stations[rng.integers(len(stations), size=count)]
    base = base + rng.normal(0.0, 0.05, size=base.shape)
    off = model.arm_offset
    arm = rng.uniform(model.lower[off:], model.upper[off:], size=(count, model.dof - off))
    return np.hstack([base, arm])


def test_verdicts_match_a_per_state_fcl_loop_on_10000_states() -> None:
    model = reference_model()
    scene = restroom_scene(doors=(30, 60, 90), seats=(0, 90, 0))
    states = _station_states(model, np.random.default_rng(21), 10_000)
    ours = CollisionChecker(model, scene).check(states, stop_at_first=False).status == COLLIDING
    naive = PerStateFCL(model, scene)
    theirs = np.array([naive.collides(s) for s in states])
    assert 0.1 < theirs.mean() < 0.9  # both outcomes are well represented
    assert np.array_equal(ours, theirs), np.flatnonzero(ours != theirs)[:10]


def _pole_scene(x: float) -> Scene:
    pole = np.eye(4)
    pole[:3, 3] = [x, 0.0, 1.0]
    return make_scene([SceneObject("pole", Shape(ShapeKind.CYLINDER, (0.05, 2.0)), pole)])


def test_pads_mark_near_states_ambiguous_and_far_ones_free() -> None:
    model = reference_model()
    state = np.array([0.0, 0.0, 0.0, *STOWED_ARM])
    checker = CollisionChecker(model, _pole_scene(0.3 + 0.05 + 0.02))  # 2 cm off the base's front
    elements = len(model.elements)
    pairs = len(checker.robot.pair_i)

    def status(pad: float) -> int:
        verdict = checker.check(
            state[None],
            element_pad=np.full((1, elements), pad),
            pair_pad=np.full((1, pairs), 0.0),
        )
        return int(verdict.status[0])

    assert status(0.0) == FREE
    assert status(0.01) == FREE
    assert status(0.03) == AMBIGUOUS
    assert int(CollisionChecker(model, _pole_scene(0.3)).check(state[None]).status[0]) == COLLIDING


def test_stop_at_first_reports_the_first_colliding_state_only() -> None:
    model = reference_model()
    checker = CollisionChecker(model, _pole_scene(1.0))
    xs = np.linspace(0.0, 2.0, 21)  # the base drives through the pole from x ≈ 0.65 on
    states = np.array([[x, 0.0, 0.0, *STOWED_ARM] for x in xs])
    every = checker.check(states, stop_at_first=False)
    first = checker.check(states, stop_at_first=True)
    hits = np.flatnonzero(every.status == COLLIDING)
    assert len(hits) > 3 and first.first_collision == hits[0]
    assert np.all(first.status[hits[0] + 1 :] == FREE)  # not looked at
    assert first.narrow_checks < every.narrow_checks
    named = {(c.link, c.other, c.kind) for c in first.contacts}
    assert ("base_link", "pole", ContactKind.SCENE) in named
    assert all(other == "pole" for _, other, _ in named)


@pytest.mark.parametrize("scene_kind", ["empty", "restroom"])
def test_state_contacts_name_self_collisions(scene_kind: str) -> None:
    model = reference_model()
    scene = make_scene([]) if scene_kind == "empty" else restroom_scene()
    folded = np.array([0.0, 0.0, 0.0, 0.0, -1.3, 0.0, 1.0, 0.0, 3.14, 0.0])  # wrist onto link5
    contacts = CollisionChecker(model, scene).state_contacts(folded)
    assert ("link5", "link7", ContactKind.SELF) in {(c.link, c.other, c.kind) for c in contacts}
