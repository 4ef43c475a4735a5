"""The planning task that worker processes run: picklable problem in, picklable result out.

`run_planning` never touches a database and never raises. Each worker process keeps the robot
models it rebuilt (LRU by model id), the scenes it parsed (LRU by scene hash) and the model
variants it built for them, so repeated queries against the same robot and scene skip URDF
parsing and scene parsing.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import replace

from trajcache.core.lru import LRU
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.scene.variant import VariantCache, model_in_scene, variant_cache
from trajcache.planning.compiled_planner import NAME as COMPILED
from trajcache.planning.compiled_planner import plan_compiled
from trajcache.planning.ompl_planner import plan_ompl
from trajcache.planning.options import SearchOptions
from trajcache.planning.problem import (
    ModelSource,
    PlannerStatus,
    PlanningProblem,
    PlanResult,
    SceneSource,
)
from trajcache.planning.rris import plan_with_rris

MODEL_CACHE_SIZE = 8
SCENE_CACHE_SIZE = 64
RRIS = "rris"

# Per process: each worker process keeps its own.
MODELS: LRU[str, RobotModel] = LRU(capacity=MODEL_CACHE_SIZE)
SCENES: LRU[str, Scene] = LRU(capacity=SCENE_CACHE_SIZE)
VARIANTS: VariantCache = variant_cache()


def model_from_source(source: ModelSource) -> RobotModel:
    """The RobotModel of `source`, rebuilt once per process and model id."""
    model = MODELS.get(source.model_id)
    if model is None:
        model = load_robot_model(
            source.urdf,
            files=source.mesh_files(),
            base=source.base,
            joint_names=source.joint_names,
            srdf=source.srdf,
            joint_values=source.joint_values,
        )
        MODELS.put(source.model_id, model)
    return model


def scene_from_source(source: SceneSource) -> Scene:
    """The parsed scene of `source`, parsed once per process and scene hash (a scene sent
    parsed is taken as it is)."""
    scene = SCENES.get(source.hash) if source.hash else None
    if scene is None:
        scene = source.parsed if source.parsed is not None else parse_scene(source.native())
        if source.hash:
            SCENES.put(source.hash, scene)
    return scene


def run_planning(problem: PlanningProblem) -> PlanResult:
    """Plan one problem with the planner it names ("compiled", "rris" or an OMPL planner);
    never raises."""
    began = time.perf_counter()
    try:
        scene = scene_from_source(problem.scene)
        model = model_in_scene(
            model_from_source(problem.model), scene, dict(problem.joint_values), cache=VARIANTS
        )
        setup_ms = (time.perf_counter() - began) * 1e3
        name = problem.planner.strip().lower()
        options = SearchOptions(
            budget_s=problem.budget_s,
            seed=problem.seed,
            shortcut_s=problem.shortcut_s,
            resolution=problem.resolution,
            certified=problem.certified_validation,
        )
        ends = (problem.start, problem.goal)
        if name == COMPILED:  # the compiled search simplifies its paths itself
            compiled = replace(options, shortcut_s=0.0)
            result = plan_compiled(model, scene, *ends, compiled)
        elif name == RRIS:
            result = plan_with_rris(model, scene, *ends, options)
        else:
            result = plan_ompl(model, scene, *ends, options, planner=name)
    except Exception as exc:  # a worker task must answer, whatever happened
        detail = traceback.format_exception_only(type(exc), exc)[-1].strip()
        result = PlanResult(PlannerStatus.ERROR, message=f"planning failed: {detail}")
        setup_ms = 0.0
    result.seed = problem.seed
    result.stats.setdefault("plan_ms", 0.0)
    result.stats.setdefault("shortcut_ms", 0.0)
    result.stats["setup_ms"] = setup_ms
    result.stats["run_ms"] = (time.perf_counter() - began) * 1e3
    return result
