"""The JSON forms of a planning task and of its result, as they travel through the Celery broker.

A task names its robot model by id and its scene by hash; the worker reads what it does not hold
yet from the shared database (`trajcache.jobs.sources`). Only a scene the database does not hold
(a seed job's generated scene) travels with its payload. Nothing is pickled: whoever can write to
the broker can ask for plans, but cannot make a worker run code.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from pydantic import TypeAdapter

from trajcache.planning.problem import (
    ModelSource,
    PlannerStatus,
    PlanningProblem,
    PlanResult,
    SceneSource,
)

__all__ = ["problem_from_message", "result_from_message", "result_message", "task_message"]

_PROBLEM: TypeAdapter[PlanningProblem] = TypeAdapter(PlanningProblem)


def task_message(problem: PlanningProblem) -> dict[str, Any]:
    """`problem` as JSON: the model by id, the scene by hash (with its payload unless stored)."""
    message: dict[str, Any] = _PROBLEM.dump_python(problem, mode="json", exclude={"model", "scene"})
    scene = problem.scene
    message["model_id"] = problem.model.model_id
    message["scene"] = {"hash": scene.hash, "payload": None if scene.stored else scene.native()}
    return message


def problem_from_message(
    message: dict[str, Any],
    *,
    model_fn: Callable[[str], ModelSource],
    scene_fn: Callable[[str, dict[str, Any] | None], SceneSource],
) -> PlanningProblem:
    """The problem a task message describes, its model and scene found by `model_fn(model_id)`
    and `scene_fn(hash, payload)`; a malformed message raises pydantic's ValidationError."""
    fields = dict(message)
    model_id, scene = str(fields.pop("model_id")), fields.pop("scene")
    source = scene_fn(str(scene["hash"]), scene.get("payload"))
    return _PROBLEM.validate_python({**fields, "model": model_fn(model_id), "scene": source})


def result_message(result: PlanResult) -> dict[str, Any]:
    """`result` as JSON (the path as a list of states)."""
    return {
        "status": result.status.value,
        "path": None if result.path is None else np.asarray(result.path, dtype=float).tolist(),
        "message": result.message,
        "stats": {str(k): float(v) for k, v in result.stats.items()},
        "seed": result.seed,
        "certificate": result.certificate,
    }


def result_from_message(message: dict[str, Any]) -> PlanResult:
    """The PlanResult of a result message."""
    path = message.get("path")
    seed = message.get("seed")
    return PlanResult(
        PlannerStatus(message["status"]),
        None if path is None else np.asarray(path, dtype=float),
        message=str(message.get("message", "")),
        stats={str(k): float(v) for k, v in (message.get("stats") or {}).items()},
        seed=None if seed is None else int(seed),
        certificate=str(message.get("certificate") or ""),
    )
