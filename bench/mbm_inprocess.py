"""The MBM problems planned in this process: the planner alone, without HTTP, database or pool.

The robot model is built once, as a planner worker builds it once per registered model
(`model_setup_ms`). Every problem is then planned cold: the process's caches of model variants,
scenes and collision geometry are emptied, and the per-scene setup is done and timed apart
(`setup_ms`): the scene parsed from the YAML as sent to the service, the model's variant for it
(its allowed pairs), and the collision geometry of both (the robot's with its self pairs proven
free). The planner then runs on that (`planner_only_ms`, see mbm_tally): the service's planning
task (`run_planning`, default resolution, certified validation), seeded per problem from
--seed, with --budget and --planner. Returned paths are dense-checked as through the service;
nothing is replayed (there is no cache here).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from mbm_check import SceneChecker, check_path, path_length
from mbm_problems import ARM_JOINTS, FAMILIES, Problem, allowed_pairs, clamp, scene_objects
from mbm_tally import Tally
from trajcache.core.config import Settings
from trajcache.geometry.collision.shared import PROCESS_GEOMETRY, robot_geometry, scene_geometry
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.scene.variant import model_in_scene
from trajcache.planning import run
from trajcache.planning.problem import SEED_LIMIT, ModelSource, PlanningProblem, SceneSource
from trajcache.planning.warm import warm

# the service's default (its settings: TRAJCACHE_DEFAULT_PLANNER), when --planner is not given
DEFAULT_PLANNER = Settings.model_fields["default_planner"].default


def model_source(args: argparse.Namespace) -> ModelSource:
    """The Panda as registered: URDF, SRDF, collision meshes, the arm joints."""
    robot_dir = args.data / "robot"
    files = {
        str(p.relative_to(robot_dir)): p.read_bytes()
        for p in sorted((robot_dir / "meshes").rglob("*"))
        if p.is_file()
    }
    return ModelSource(
        model_id="mbm-panda",
        urdf=(robot_dir / "panda.urdf").read_text(encoding="utf-8"),
        base="fixed",
        joint_names=ARM_JOINTS,
        files=files,
        srdf=(robot_dir / "panda.srdf").read_text(encoding="utf-8"),
    )


def cold_setup(model: RobotModel, problem: Problem) -> tuple[SceneSource, float]:
    """Empty the process's caches, then build the problem's scene, model variant and collision
    geometry; the scene as the planner finds it, and the time taken (ms)."""
    run.VARIANTS.clear()
    run.SCENES.clear()
    PROCESS_GEOMETRY.clear()
    began = time.perf_counter()
    scene = parse_scene(problem.scene)
    variant = model_in_scene(model, scene, {}, cache=run.VARIANTS)
    robot_geometry(variant)
    scene_geometry(scene)
    setup_ms = (time.perf_counter() - began) * 1e3
    run.SCENES.put(scene.hash, scene)
    return SceneSource(scene.hash, problem.scene), setup_ms


def plan_problem(
    tally: Tally, checker: SceneChecker, source: ModelSource, problem: Problem, args: Any
) -> None:
    """Plan one problem cold, time it, and dense-check its path."""
    tally.problems += 1
    start, moved_start = clamp(problem.start, checker.lower, checker.upper)
    goal, moved_goal = clamp(problem.goal, checker.lower, checker.upper)
    tally.clamped_starts += moved_start
    tally.clamped_goals += moved_goal
    rng = np.random.default_rng([args.seed, FAMILIES.index(problem.family), problem.index])
    scene, setup_ms = cold_setup(run.model_from_source(source), problem)
    result = run.run_planning(
        PlanningProblem(
            source, scene, tuple(start.tolist()), tuple(goal.tolist()),
            budget_s=args.budget, planner=args.planner or DEFAULT_PLANNER,
            seed=int(rng.integers(1, SEED_LIMIT + 1)),
        )
    )  # fmt: skip
    stats = result.stats
    tally.setup_ms.append(setup_ms + stats.get("setup_ms", 0.0))  # the latter: cache lookups
    if not result.solved or result.path is None:
        tally.notes[f"{result.status.value}: {result.message[:120]}"] += 1
        return
    tally.solved += 1
    worker = stats.get("run_ms", 0.0) - stats.get("setup_ms", 0.0)
    search = stats.get("search_ms", stats.get("plan_ms", 0.0))
    tally.planner_ms.append(search + stats.get("simplify_ms", 0.0) + stats.get("shortcut_ms", 0.0))
    tally.worker_ms.append(worker)
    tally.record_extras({"planner": args.planner or DEFAULT_PLANNER, **stats})
    states = np.asarray(result.path, dtype=float)
    tally.path_lengths.append(path_length(states))
    checker.set_scene(scene_objects(problem.scene), allowed_pairs(problem.scene))
    check_path(tally, checker, states, (start, goal), f"plan {problem.label}")


def run_in_process(
    problems: list[Problem], checker: SceneChecker, args: argparse.Namespace
) -> tuple[list[Tally], dict[str, Any]]:
    """Plan every problem in this process; a tally per family, and the one-off setup times."""
    began = time.perf_counter()
    warm()  # the compiled kernels, loaded (or compiled) before anything is timed
    warm_s = time.perf_counter() - began
    source = model_source(args)
    began = time.perf_counter()
    run.model_from_source(source)
    model_ms = (time.perf_counter() - began) * 1e3
    tallies: dict[str, Tally] = {}
    for problem in problems:
        tally = tallies.setdefault(problem.family, Tally(problem.family))
        plan_problem(tally, checker, source, problem, args)
    setup = {"model_setup_ms": round(model_ms, 2), "warm_s": round(warm_s, 1)}
    return list(tallies.values()), setup
