"""The per-state FCL loops the validation benchmark compares against, and its turn-taking timer.

`NaiveChecker` is the obvious implementation: for each state, move every FCL object, ask the
scene manager, then ask the robot's own manager for every contact and drop the pairs the model
allows. On a mesh robot most of its time goes into listing the triangle contacts of adjacent
links (allowed pairs) only to drop them. `PairChecker` is the same loop asking FCL only about
the self pairs it must check, one yes/no query each: a fairer per-state baseline there.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import fcl
import numpy as np

from trajcache.geometry.model.kinematics import element_transforms, link_transforms
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.scene import Scene


class NaiveChecker:
    """The obvious implementation: for each state, move every FCL object and ask the managers."""

    def __init__(self, model: RobotModel, scene: Scene) -> None:
        self.model = model
        self.geoms = [e.shape.to_fcl() for e in model.elements]
        self.objs = [fcl.CollisionObject(g, fcl.Transform()) for g in self.geoms]
        self.link_of = {id(g): e.link for g, e in zip(self.geoms, model.elements, strict=True)}
        self.robot = fcl.DynamicAABBTreeCollisionManager()
        self.robot.registerObjects(self.objs)
        self.robot.setup()
        self.scene = fcl.DynamicAABBTreeCollisionManager()
        self.scene.registerObjects(
            [
                fcl.CollisionObject(o.shape.to_fcl(), fcl.Transform(o.pose[:3, :3], o.pose[:3, 3]))
                for o in scene.objects
            ]
        )
        self.scene.setup()

    def place(self, state: np.ndarray) -> None:
        """FK of one state; moves every robot object and updates the robot's manager."""
        poses = element_transforms(self.model, link_transforms(self.model, state[None, :]))[0]
        for obj, pose in zip(self.objs, poses, strict=True):
            obj.setTransform(fcl.Transform(pose[:3, :3], pose[:3, 3]))
        self.robot.update()

    def hits_scene(self) -> bool:
        """Whether the placed robot touches the scene."""
        data = fcl.CollisionData(request=fcl.CollisionRequest())
        self.robot.collide(self.scene, data, fcl.defaultCollisionCallback)
        return bool(data.result.is_collision)

    def state_collides(self, state: np.ndarray) -> bool:
        """Per-state check: FK of one state, update the manager, scene then self collisions."""
        self.place(state)
        if self.hits_scene():
            return True
        request = fcl.CollisionRequest(num_max_contacts=100_000, enable_contact=True)
        data = fcl.CollisionData(request=request)
        self.robot.collide(data, fcl.defaultCollisionCallback)
        for contact in data.result.contacts:
            a, b = self.link_of[id(contact.o1)], self.link_of[id(contact.o2)]
            if a != b and (min(a, b), max(a, b)) not in self.model.allowed_pairs:
                return True
        return False

    def validate(self, samples: np.ndarray) -> bool:
        """True when every sample is free; stops at the first collision."""
        return not any(self.state_collides(s) for s in samples)


class PairChecker(NaiveChecker):
    """The naive loop asking FCL about each self pair it must check, without contact lists."""

    def __init__(self, model: RobotModel, scene: Scene) -> None:
        super().__init__(model, scene)
        links = [e.link for e in model.elements]
        self.pairs = [
            (self.objs[i], self.objs[j])
            for i in range(len(links))
            for j in range(i + 1, len(links))
            if links[i] != links[j]
            and (min(links[i], links[j]), max(links[i], links[j])) not in model.allowed_pairs
        ]

    def state_collides(self, state: np.ndarray) -> bool:
        """Per-state check: scene through the managers, then one FCL query per checked pair."""
        self.place(state)
        if self.hits_scene():
            return True
        request = fcl.CollisionRequest()
        return any(fcl.collide(a, b, request, fcl.CollisionResult()) for a, b in self.pairs)


def timed_runs(fns: list[Callable[[], object]], repeats: int) -> tuple[list[float], list[object]]:
    """Median wall time of each of `fns` in seconds and what its last call returned, taking turns
    so that a change in the machine's load hits them alike."""
    times: list[list[float]] = [[] for _ in fns]
    returned: list[object] = [None] * len(fns)
    for _ in range(repeats):
        for k, (fn, spent) in enumerate(zip(fns, times, strict=True)):
            began = time.perf_counter()
            returned[k] = fn()
            spent.append(time.perf_counter() - began)
    return [statistics.median(t) for t in times], returned


def timed(fns: list[Callable[[], object]], repeats: int) -> list[float]:
    """Median wall time of each of `fns` in seconds, taking turns (see `timed_runs`)."""
    return timed_runs(fns, repeats)[0]
