"""bench/load.py's robot scripts: each robot's requests, encoded once before the load starts.

A robot replays cleaning runs; before each call it brings its scene up to date (PUT, then PATCH
of what changed), and about a given share of its arm moves are replaced by a novel request that
no cached trajectory serves (`MissMaker`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from trajcache.core.config import Settings
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import build_validator
from trajcache.reference.cleaning import CleaningRun, PlanCall

PLAN_OPTIONS = {"fallback": True}
MISS_OFFSET_RAD = (0.22, 0.4)  # how far a miss's endpoint joints move (threshold: 0.2)
MISS_JOINTS = 3


@dataclass(frozen=True)
class Step:
    """One request of a robot's script, encoded once before the load starts."""

    kind: str  # "scene", "hit" (a call of the run) or "miss" (a novel request)
    method: str
    path: str
    body: bytes
    scene_hash: str = ""  # a scene step: the hash the service must answer


def scene_step(robot_id: str, scene: Scene, shown: dict[str, Any] | None) -> Step:
    """The request that makes `scene` the robot's scene: PUT at first, then a PATCH."""
    payload = scene_to_payload(scene)
    path = f"/v1/robots/{robot_id}/scene"
    if shown is None:
        return Step("scene", "PUT", path, json.dumps(payload).encode(), scene.hash)
    before = {o["id"]: o for o in shown["objects"]}
    after = {o["id"]: o for o in payload["objects"]}
    env: dict[str, float | None] = {
        k: v for k, v in payload["env"].items() if shown["env"].get(k) != v
    }
    env.update({k: None for k in shown["env"] if k not in payload["env"]})
    patch = {
        "upsert": [o for oid, o in after.items() if before.get(oid) != o],
        "remove": [oid for oid in before if oid not in after],
        "env": env,
    }
    return Step("scene", "PATCH", path, json.dumps(patch).encode(), scene.hash)


class MissMaker:
    """Novel, collision-free plan requests near the workload's arm moves."""

    def __init__(self, model: RobotModel, seed: int) -> None:
        self.model = model
        self.rng = np.random.default_rng(seed)
        arm = slice(3, model.dof)
        self.lower = np.maximum(model.lower[arm], -np.pi)
        self.upper = np.minimum(model.upper[arm], np.pi)
        self._checkers: dict[str, Any] = {}
        self._settings = Settings()

    def _free(self, scene: Scene, state: np.ndarray) -> bool:
        checker = self._checkers.get(scene.hash)
        if checker is None:
            checker = build_validator(self.model, scene, self._settings).checker
            self._checkers[scene.hash] = checker
        return not checker.state_contacts(state)

    def _moved(self, state: np.ndarray) -> np.ndarray | None:
        moved = state.copy()
        joints = self.rng.choice(len(self.lower), MISS_JOINTS, replace=False)
        offsets = self.rng.uniform(*MISS_OFFSET_RAD, MISS_JOINTS)
        signs = self.rng.choice([-1.0, 1.0], MISS_JOINTS)
        moved[3 + joints] += signs * offsets
        arm = moved[3:]
        if np.any(arm < self.lower) or np.any(arm > self.upper):
            return None
        return moved

    def make(self, call: PlanCall, scene: Scene) -> tuple[np.ndarray, np.ndarray] | None:
        """Start and goal of a miss derived from `call`, or None if none was found."""
        for _ in range(30):
            start, goal = self._moved(call.start), self._moved(call.goal)
            if start is None or goal is None:
                continue
            if self._free(scene, start) and self._free(scene, goal):
                return start, goal
        return None


def plan_step(robot_id: str, kind: str, start: np.ndarray, goal: np.ndarray) -> Step:
    """A plan request."""
    body = {"start": start.tolist(), "goal": goal.tolist(), "options": PLAN_OPTIONS}
    return Step(kind, "POST", f"/v1/robots/{robot_id}/plan", json.dumps(body).encode())


def robot_script(
    robot_id: str, runs: list[CleaningRun], calls: int | None, misses: MissMaker, share: float
) -> list[Step]:
    """The requests of one robot replaying the first `calls` calls of each of `runs`."""
    steps: list[Step] = []
    shown: dict[str, Any] | None = None
    shown_hash = ""
    for run in runs:
        played = run.calls[:calls]
        arm_moves = [c.index for c in played if not c.base_moves]
        count = min(len(arm_moves), round(share * len(played)))
        chosen = set(misses.rng.choice(arm_moves, count, replace=False).tolist())
        for call in played:
            scene = run.scene_for(call)
            if scene.hash != shown_hash:
                steps.append(scene_step(robot_id, scene, shown))
                shown, shown_hash = scene_to_payload(scene), scene.hash
            miss = misses.make(call, scene) if call.index in chosen else None
            if miss is not None:
                steps.append(plan_step(robot_id, "miss", *miss))
            else:
                steps.append(plan_step(robot_id, "hit", call.start, call.goal))
    return steps
