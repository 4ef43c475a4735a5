"""The worker task: picklable end to end, cached per process, never raising."""

from __future__ import annotations

import multiprocessing
import pickle
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np
import pytest

from tests.planning.test_ompl_planner import DOWN, FORWARD
from tests.waiting import NEVER_BINDS_S
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.validation.validator import Resolution, TrajectoryValidator
from trajcache.planning import ompl_planner, rris, run
from trajcache.planning.problem import (
    ModelSource,
    PlannerStatus,
    PlanningProblem,
    PlanResult,
    SceneSource,
)
from trajcache.planning.query import prepare_query
from trajcache.planning.run import run_planning
from trajcache.reference.restroom import restroom_layout, restroom_scene
from trajcache.reference.robot import reference_model, reference_urdf


@pytest.fixture(scope="module")
def problem() -> PlanningProblem:
    model = reference_model()
    scene = restroom_scene(doors=45.0)
    station = restroom_layout().station("stall_2")
    base = (station.x, station.y, station.theta)
    source = ModelSource(
        model_id=model.model_id,
        urdf=reference_urdf(),
        base=model.base.value,
        joint_names=model.joint_names,
    )
    return PlanningProblem(
        model=source,
        scene=SceneSource(scene.hash, scene_to_payload(scene)),
        start=base + DOWN,
        goal=base + FORWARD,
        budget_s=NEVER_BINDS_S,
        seed=1,
    )


def cache_sizes() -> tuple[int, int, int, int]:
    """(models cached, model cache hits, scenes cached, scene cache hits) in this process."""
    return len(run.MODELS), run.MODELS.hits, len(run.SCENES), run.SCENES.hits


def test_a_scene_sent_parsed_is_planned_in_as_it_is(
    problem: PlanningProblem, monkeypatch: pytest.MonkeyPatch
) -> None:
    scene = restroom_scene(doors=45.0)
    sent = pickle.loads(pickle.dumps(replace(problem, scene=SceneSource.of(scene), seed=3)))
    assert sent.scene.parsed is not None and sent.scene.parsed.hash == scene.hash
    assert sent.scene.payload is None
    run.SCENES.clear()

    def no_parsing(payload: object) -> None:
        raise AssertionError("a scene sent parsed was parsed again")

    monkeypatch.setattr(run, "parse_scene", no_parsing)
    result = run_planning(sent)
    assert result.status is PlannerStatus.SOLVED, result.message
    assert run.SCENES.get(scene.hash) is sent.scene.parsed


def test_run_planning_in_a_worker_process(problem: PlanningProblem) -> None:
    restored = pickle.loads(pickle.dumps(problem))
    context = multiprocessing.get_context("spawn")  # a fresh interpreter, as in production
    with ProcessPoolExecutor(max_workers=1, mp_context=context) as pool:
        first = pool.submit(run_planning, restored).result(timeout=120)
        second = pool.submit(run_planning, replace(restored, seed=2)).result(timeout=120)
        models, model_hits, scenes, scene_hits = pool.submit(cache_sizes).result(timeout=60)
    for result in (first, second):
        assert isinstance(result, PlanResult)
        assert result.status is PlannerStatus.SOLVED, result.message
        assert result.path is not None and np.allclose(result.path[0], problem.start)
        for key in ("plan_ms", "shortcut_ms", "length_before", "length_after", "checks"):
            assert key in result.stats
    # the second call skipped URDF loading and scene parsing: it found both in the worker's
    # caches (counted, not timed: a cache hit's setup time says nothing on a busy machine)
    assert (models, model_hits, scenes, scene_hits) == (1, 1, 1, 1)
    assert first.stats["setup_ms"] > 0.0 and second.stats["setup_ms"] > 0.0
    assert pickle.loads(pickle.dumps(first)).status is PlannerStatus.SOLVED


@pytest.mark.parametrize("planner", ["rrtconnect", "rris"])
def test_the_seed_is_reported_and_repeats_the_search(
    problem: PlanningProblem, planner: str
) -> None:
    first = run_planning(replace(problem, planner=planner, seed=11))
    again = run_planning(replace(problem, planner=planner, seed=11))
    other = run_planning(replace(problem, planner=planner, seed=12))
    assert (first.seed, again.seed, other.seed) == (11, 11, 12)
    raw = [r.stats["length_before"] for r in (first, again, other)]  # before time-bound passes
    assert raw[0] == raw[1] and raw[0] != raw[2]


@pytest.mark.parametrize("planner", ["rrtconnect", "rris"])
def test_the_validator_settings_reach_the_planners_checks(
    problem: PlanningProblem, planner: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    built: list[tuple[Resolution, bool]] = []  # validators: resolution, certified
    checked: list[Resolution] = []  # motion checks: resolution

    class Recording(TrajectoryValidator):
        def __init__(self, *args: object, **kwargs: object) -> None:
            super().__init__(*args, **kwargs)  # type: ignore[arg-type]
            built.append((self.resolution, self.certified))

    def recording_query(*args: object, **kwargs: object) -> object:
        query = prepare_query(*args, **kwargs)  # type: ignore[arg-type]
        checked.append(query.spec.resolution)  # type: ignore[union-attr]
        return query

    for module in (ompl_planner, rris):
        monkeypatch.setattr(module, "TrajectoryValidator", Recording)
        monkeypatch.setattr(module, "prepare_query", recording_query)
    settings = {"step_position_m": 0.03, "step_orientation_rad": 0.02, "step_joint_rad": 0.01}
    fine = replace(problem, planner=planner, certified_validation=False, **settings)
    result = run_planning(fine)
    assert result.status is PlannerStatus.SOLVED, result.message
    assert (built, checked) == (
        [(Resolution(0.03, 0.02, 0.01), False)],
        [Resolution(0.03, 0.02, 0.01)],
    )
    assert run_planning(replace(problem, planner=planner)).status is PlannerStatus.SOLVED
    assert (built[1:], checked[1:]) == ([(Resolution(), True)], [Resolution()])


def test_rris_is_dispatched_by_name(problem: PlanningProblem) -> None:
    result = run_planning(replace(problem, planner="RRIS"))
    assert result.status is PlannerStatus.SOLVED, result.message
    assert result.stats["length_after"] <= result.stats["length_before"] + 1e-9


def test_failures_are_results_not_exceptions(problem: PlanningProblem) -> None:
    truncated = "<robot"  # a literal: the malformation is what is tested
    broken = replace(problem, model=replace(problem.model, model_id="broken", urdf=truncated))
    result = run_planning(broken)
    assert result.status is PlannerStatus.ERROR and "planning failed" in result.message
    bad_scene = replace(problem, scene=SceneSource("bad", {"objects": [{"id": 1}]}))
    assert run_planning(bad_scene).status is PlannerStatus.ERROR
    unknown = run_planning(replace(problem, planner="dijkstra"))
    assert unknown.status is PlannerStatus.ERROR and "rrtconnect" in unknown.message
    short = run_planning(replace(problem, start=problem.start[:5]))
    assert short.status is PlannerStatus.INVALID_START
