"""A seed job expanded into its work: the scenes and, in order, the plan requests to run.

`expand` validates the job against the model and the settings (states within the limits,
the bounds on scenes, requests and options) and builds each scene once.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from trajcache.core.config import Settings
from trajcache.geometry.errors import GeometryError
from trajcache.geometry.model.kinematics import check_limits, check_states
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.scene import Scene
from trajcache.reference.cleaning import cleaning_run, door_sweep_run
from trajcache.services.errors import InvalidInputError, PayloadTooLargeError
from trajcache.services.seeding.scenes import build_scenes
from trajcache.services.seeding.spec import SeedJobSpec, SeedQuery, Workload


@dataclass(frozen=True, eq=False)
class SeedItem:
    """One plan request of a job: a scene (index into the job's scenes), start, goal."""

    scene: int
    start: np.ndarray
    goal: np.ndarray
    label: str


@dataclass(frozen=True, eq=False)
class SeedWork:
    """A job expanded: its scenes and its work items in order."""

    scenes: list[Scene]
    items: list[SeedItem]


def _check_items(total: int, settings: Settings) -> None:
    if total > settings.seed_max_queries:
        raise PayloadTooLargeError(
            f"the job has {total} plan requests, more than "
            f"seed_max_queries={settings.seed_max_queries}"
        )


def _checked(model: RobotModel, states: Iterable[Any], name: str) -> np.ndarray:
    try:
        array = check_states(model, list(states), name=name)
        check_limits(model, array, name=name)
    except GeometryError as exc:
        raise InvalidInputError(str(exc)) from None
    return array


def _query_items(queries: Sequence[SeedQuery], model: RobotModel, n_scenes: int) -> list[SeedItem]:
    """Every query in its scenes, scene-major (one scene's requests run together)."""
    for j, query in enumerate(queries):
        _checked(model, query.start, f"queries[{j}].start")
        _checked(model, query.goal, f"queries[{j}].goal")
        if query.scene is not None and query.scene >= n_scenes:
            raise InvalidInputError(
                f"queries[{j}].scene: {query.scene} is not a scene index (0..{n_scenes - 1})"
            )
    items: list[SeedItem] = []
    for s in range(n_scenes):
        for j, query in enumerate(queries):
            if query.scene is None or query.scene == s:
                start, goal = np.asarray(query.start, float), np.asarray(query.goal, float)
                items.append(SeedItem(s, start, goal, f"scene {s}, query {j}"))
    return items


def _workload_items(workload: Workload, model: RobotModel) -> SeedWork:
    if workload.name == "cleaning":
        runs = [("", cleaning_run(workload.seed, perturbed=workload.perturbed))]
    else:
        angles = workload.door_angles()
        for k, angle in enumerate(angles):
            if not 0.0 <= angle <= 90.0:
                raise InvalidInputError(f"workload.doors_deg[{k}]: {angle} is not within 0..90")
        runs = [(f"doors {a:g}°, ", door_sweep_run(a, workload.seed)) for a in angles]
    scenes: list[Scene] = []
    index: dict[str, int] = {}
    items: list[SeedItem] = []
    for prefix, run in runs:
        calls = run.calls[: workload.limit]
        where = f"workload {workload.name!r} (for the reference robot)"
        _checked(model, [c.start for c in calls] + [c.goal for c in calls], where)
        for call in calls:
            scene = run.scene_for(call)
            if scene.hash not in index:
                index[scene.hash] = len(scenes)
                scenes.append(scene)
            label = f"{prefix}call {call.index}: {call.label}"
            items.append(SeedItem(index[scene.hash], call.start, call.goal, label))
    return SeedWork(scenes, items)


def expand(spec: SeedJobSpec, *, model: RobotModel, settings: Settings) -> SeedWork:
    """The job's scenes and work items; InvalidInputError names what is wrong (422)."""
    if spec.concurrency is not None and spec.concurrency > settings.seed_concurrency:
        raise InvalidInputError(
            f"concurrency: {spec.concurrency} is above seed_concurrency={settings.seed_concurrency}"
        )
    options = spec.options
    for name, value, setting in (
        ("threshold", options.threshold, "lookup_threshold_max"),
        ("max_candidates", options.max_candidates, "max_candidates_limit"),
        ("budget_s", options.budget_s, "plan_budget_max_s"),
    ):
        limit = getattr(settings, setting)
        if value is not None and value > limit:
            raise InvalidInputError(f"options.{name}: {value} is above {setting}={limit}")
    if spec.workload is not None:
        work = _workload_items(spec.workload, model)
        _check_items(len(work.items), settings)
        return work
    scenes = build_scenes(
        scenes=spec.scenes,
        base_scene=spec.base_scene,
        variants=spec.variants,
        sweep=spec.sweep,
        settings=settings,
    )
    assert spec.queries is not None
    _check_items(sum(len(scenes) if q.scene is None else 1 for q in spec.queries), settings)
    return SeedWork(scenes, _query_items(spec.queries, model, len(scenes)))
