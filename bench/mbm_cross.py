"""`bench/mbm.py --cross-scene`: solved MBM problems asked again in changed scenes.

- Moved (part 1): the problem's own scene with one object (chosen at random) moved by up to
  1 cm in a random direction, then the problem's start and goal, lookup on. A hit's validation
  builds on the cached path's stored certificate (`validation.reused` "certificate"): only the
  new first and last segments, and the interior against the moved object, are proved again.
  `moved_cache_rate` (answers from the cache over asked), `moved_validate_ms_median` (the hits'
  `timings_ms.validate`), `pairs_reproved_share` ((path, object) pairs proved again over those
  checked, on hits that used a certificate), `pairs_clear_share` (those found clear of the
  certificate's swept envelope instead).
- Cross (part 2): the family's next scene (every object elsewhere), the problem's start and goal.
  Counted over the problems whose ends are free there (a start or goal in collision is a 422,
  counted as `cross_ends_invalid`): `cross_cache_rate` (answers from the cache or repaired from
  a cached path), `cross_repaired`, `cross_server_ms_median` (of those answers), and on hits
  that used a certificate `cross_pairs_reproved_share` and `cross_pairs_clear_share`.

Every returned path is dense-checked in the scene it was asked in, as the rest of the benchmark.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import yaml

from dense_mesh import FloatArray
from mbm_check import SceneChecker, check_path
from mbm_problems import Problem, allowed_pairs, scene_objects
from mbm_tally import Tally
from trajcache_client import APIError, Client, PlanResult

MOVE_M = 0.01


def moved_scene(scene: dict[str, Any], rng: np.random.Generator) -> tuple[dict[str, Any], str]:
    """The scene with one of its world objects moved by up to `MOVE_M`, and that object's id."""
    out = copy.deepcopy(scene)
    objects = out["world"]["collision_objects"]
    chosen = objects[int(rng.integers(len(objects)))]
    direction = rng.normal(size=3)
    shift = direction / np.linalg.norm(direction) * rng.uniform(0.0, MOVE_M)
    # the object's own pose when it has one (its shapes' poses are relative to it), else each
    # shape's pose
    poses = [chosen["pose"]] if chosen.get("pose") else []
    poses = poses or chosen.get("primitive_poses", []) + chosen.get("mesh_poses", [])
    for pose in poses:
        position = pose["position"]
        if isinstance(position, dict):
            for axis, d in zip("xyz", shift, strict=True):
                position[axis] = float(position[axis]) + float(d)
        else:
            pose["position"] = [float(v) + float(d) for v, d in zip(position, shift, strict=True)]
    return out, str(chosen["id"])


class CrossScenes:
    """The two parts, on a running service through `client`."""

    def __init__(self, client: Client, checker: SceneChecker, options: dict[str, Any]) -> None:
        self.client, self.checker, self.options = client, checker, options

    def ask(
        self, tally: Tally, robot_id: str, scene: dict[str, Any], ends: tuple[FloatArray, ...]
    ) -> PlanResult | None:
        """Put `scene` for the robot, ask start → goal with lookup on; None on a 4xx."""
        self.client.put_scene(robot_id, yaml.safe_dump(scene), media_type="application/yaml")
        self.checker.set_scene(scene_objects(scene), allowed_pairs(scene))
        try:
            answer = self.client.plan(
                robot_id, ends[0].tolist(), ends[1].tolist(), {**self.options, "lookup": True}
            )
        except APIError as exc:
            tally.counts["http_5xx" if exc.status_code >= 500 else "http_4xx_cross"] += 1
            tally.notes[f"cross {exc.status_code}: {exc.detail[:120]}"] += 1
            return None
        if answer.states is not None:
            states = np.asarray(answer.states, dtype=float)
            check_path(tally, self.checker, states, (ends[0], ends[1]), f"cross {robot_id}")
        return answer

    def moved(
        self, tally: Tally, problem: Problem, ends: tuple[FloatArray, FloatArray], seed: int
    ) -> None:
        """Part 1: one object moved by up to 1 cm."""
        rng = np.random.default_rng([seed, problem.index, 7])
        scene, _ = moved_scene(problem.scene, rng)
        answer = self.ask(tally, f"mbm-{problem.label}", scene, ends)
        tally.moved_asked += 1
        if answer is None or answer.source != "cache":
            return
        tally.moved_hits += 1
        tally.moved_validate_ms.append(float(answer.timings_ms["validate"]))
        reuse = answer.validation
        if reuse is not None and reuse.reused == "certificate" and reuse.objects:
            tally.moved_pairs += reuse.objects
            tally.moved_reproved += reuse.objects_reproved or 0
            tally.moved_clear += reuse.objects_clear or 0

    def cross(
        self, tally: Tally, problem: Problem, ends: tuple[FloatArray, FloatArray], other: Problem
    ) -> None:
        """Part 2: the family's next scene."""
        answer = self.ask(tally, f"mbm-{problem.label}", other.scene, ends)
        if answer is None:
            tally.counts["cross_ends_invalid"] += 1
            return
        tally.cross_asked += 1
        if answer.source == "cache":
            tally.cross_hits += 1
            tally.cross_server_ms.append(float(answer.timings_ms["total"]))
            reuse = answer.validation
            if reuse is not None and reuse.reused == "certificate" and reuse.objects:
                tally.cross_pairs += reuse.objects
                tally.cross_reproved += reuse.objects_reproved or 0
                tally.cross_clear += reuse.objects_clear or 0
        elif answer.source == "repaired":
            tally.cross_repaired += 1
            tally.cross_server_ms.append(float(answer.timings_ms["total"]))
        elif answer.ok:
            tally.counts["cross_planned"] += 1
