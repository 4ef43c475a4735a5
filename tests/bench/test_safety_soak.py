"""bench/safety_soak.py: its unsafe check can fail, and the smoke soak runs clean end to end."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any, cast

import numpy as np
import pytest

from harness.dense import DenseChecker, reference_checker
from safety_soak import SMOKE_PLANS, Request, Soak
from soak_geometry import grazing_radius, judge, path_obstacle, sphere
from trajcache.cache.adapt import adapt_trajectory
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.scene.payload import apply_patch
from trajcache.geometry.scene.scene import Scene
from trajcache.reference.restroom import restroom_scene
from trajcache.reference.tasks import task_state, work_station

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "safety_soak.py"


@pytest.fixture(scope="module")
def checker() -> DenseChecker:
    return reference_checker()


def _arm_move(first: str, second: str) -> np.ndarray:
    station = work_station("stall_2")
    return np.stack([task_state(station, first), task_state(station, second)])


def test_a_path_through_a_placed_obstacle_is_unsafe_and_its_endpoints_are_not(
    checker: DenseChecker,
) -> None:
    path = _arm_move("stow", "spray_rim")
    start, goal = path[0], path[-1]
    scene = restroom_scene()
    assert not judge(checker, scene, path, start, goal).unsafe
    obstacle = path_obstacle(checker, path, "obstacle_0", np.random.default_rng(0))
    assert obstacle is not None
    blocked = apply_patch(scene, {"upsert": [obstacle]})
    verdict = judge(checker, blocked, path, start, goal)
    assert verdict.collides and verdict.unsafe
    assert any(contact.endswith("obstacle_0") for contact in verdict.contacts)
    for state in (start, goal):  # the request itself is no 422
        assert not judge(checker, blocked, np.stack([state, state]), state, state).collides


class _Answering:
    """Stands in for the soak's robot: holds a scene and answers every plan with `states`."""

    def __init__(self, scene: Scene, states: np.ndarray) -> None:
        self.scene, self.states = scene, states

    def ask(self, start: Any, goal: Any, options: Any) -> tuple[int, dict[str, Any]]:
        answer = {"status": "success", "source": "cache", "trajectory_id": 7}
        return 200, {**answer, "states": self.states.tolist(), "rejected": []}


@pytest.mark.parametrize("blocked", [False, True])
def test_the_soak_counts_a_colliding_answer_as_unsafe(checker: DenseChecker, blocked: bool) -> None:
    path = _arm_move("stow", "spray_rim")
    scene = restroom_scene()
    if blocked:  # the robot's scene now holds a sphere on the path the service answers with
        obstacle = path_obstacle(checker, path, "obstacle_0", np.random.default_rng(0))
        assert obstacle is not None
        scene = apply_patch(scene, {"upsert": [obstacle]})
    soak = Soak(cast(Any, _Answering(scene, path)), checker, seed=0, model_id="m")
    soak.request(Request("blocked", path[0], path[-1], target=7))
    assert soak.tally["hits"] == 1 and soak.tally["blocked_hits_target"] == 1
    assert soak.tally["unsafe"] == soak.tally["collisions"] == int(blocked)
    assert len(soak.unsafe_cases) == int(blocked)


def test_a_grazing_sphere_only_just_reaches_into_the_path(checker: DenseChecker) -> None:
    path = _arm_move("stow", "spray_rim")
    start, goal = path[0], path[-1]
    on_link = path_obstacle(checker, path, "deep", np.random.default_rng(1))
    assert on_link is not None
    centre = np.asarray(on_link["pose"]["position"]) + np.array([0.15, 0.0, 0.0])
    radius = grazing_radius(checker, [path], centre, high=0.25)
    assert radius is not None and 0.01 < radius < 0.25
    scene = restroom_scene()
    for r, hits in ((radius + 0.002, True), (radius - 0.002, False)):
        grazed = apply_patch(scene, {"upsert": [sphere("graze", centre, r)]})
        assert judge(checker, grazed, path, start, goal).collides is hits


def test_answers_off_the_request_or_out_of_limits_are_unsafe(checker: DenseChecker) -> None:
    path = _arm_move("stow", "lift_seat")
    scene = restroom_scene()
    moved = path[-1] + np.r_[np.zeros(3), 0.01, np.zeros(6)]
    assert judge(checker, scene, path, path[0], moved).misjoined
    beyond = path.copy()
    beyond[-1, 4] = 3.0  # joint 2 stops at 2.0944 rad
    verdict = judge(checker, scene, beyond, beyond[0], beyond[-1])
    assert verdict.out_of_limits and verdict.unsafe


def test_adaptation_keeps_a_still_base_and_reverses() -> None:
    path = np.array([[0.0] * 10, [0.5, 0.0, 0.0, *[0.3] * 7], [0.0, 0.0, 0.0, *[0.6] * 7]])
    start, goal = np.full(10, 0.01), np.r_[0.01, 0.01, 0.01, [0.02] * 7]
    out = adapt_trajectory(path, start, goal, base=BaseType.PLANAR, reverse=True)
    assert np.allclose(out[0], start) and np.allclose(out[-1], goal)
    assert np.allclose(out[1], [0.01, 0.01, 0.01, *[0.3] * 7])


@pytest.mark.slow
def test_smoke_soak_is_safe_and_blocks_cached_paths() -> None:
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "--smoke"],
        capture_output=True,
        text=True,
        timeout=240,
        check=False,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    assert summary["unsafe"] == 0 and summary["http_5xx"] == 0
    assert summary["plans"] >= SMOKE_PLANS
    assert summary["hits"] > 0 and summary["planned"] > 0
    assert summary["blocked_candidates_confirmed"] > 0
    assert summary["blocked_hits_target"] == 0
    assert sum(summary["scene_changes"].values()) > summary["path_obstacles"]
