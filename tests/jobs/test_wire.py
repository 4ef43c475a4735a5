"""The JSON forms of a Celery planning task and of its result."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from pydantic import ValidationError

from tests.robots import OPAQUE_URDF
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.jobs.wire import (
    problem_from_message,
    result_from_message,
    result_message,
    task_message,
)
from trajcache.planning.problem import (
    ModelSource,
    PlannerStatus,
    PlanningProblem,
    PlanResult,
    SceneSource,
)

MESH = bytes(range(256))
MODEL = ModelSource("model-1", OPAQUE_URDF, "fixed", ("j1", "j2"), files={"mesh.stl": MESH})
PAYLOAD = {"objects": [{"id": "box", "type": "box", "size": [0.1, 0.1, 0.1]}]}


def problem(*, stored: bool) -> PlanningProblem:
    scene = SceneSource("scene-hash", PAYLOAD, stored=stored)
    return PlanningProblem(
        MODEL, scene, (0.0, 0.5), (1.0, -1.0), budget_s=1.5, seed=7, joint_values=(("j3", 0.2),)
    )


def test_a_task_names_its_model_and_a_stored_scene_without_their_content() -> None:
    message = task_message(problem(stored=True))
    text = json.dumps(message)  # JSON, nothing else
    assert message["model_id"] == "model-1"
    assert message["scene"] == {"hash": "scene-hash", "payload": None}
    assert "urdf" not in message and "files" not in message and OPAQUE_URDF[:40] not in text


def test_a_scene_no_database_holds_travels_with_its_payload() -> None:
    scene = task_message(problem(stored=False))["scene"]
    assert scene == {"hash": "scene-hash", "payload": PAYLOAD}


@pytest.mark.parametrize("stored", [True, False])
def test_the_worker_rebuilds_the_problem_from_what_it_reads(stored: bool) -> None:
    original = problem(stored=stored)
    asked: list[object] = []

    def scene_fn(scene_hash: str, payload: dict[str, object] | None) -> SceneSource:
        asked.append((scene_hash, payload))
        return original.scene

    message = json.loads(json.dumps(task_message(original)))
    rebuilt = problem_from_message(message, model_fn=lambda _: MODEL, scene_fn=scene_fn)
    assert rebuilt == original
    assert asked == [("scene-hash", None if stored else PAYLOAD)]


def test_a_malformed_task_is_a_validation_error() -> None:
    message = task_message(problem(stored=False))
    message["start"] = "nowhere"
    with pytest.raises(ValidationError):
        problem_from_message(
            message, model_fn=lambda _: MODEL, scene_fn=lambda h, p: SceneSource(h, p or {})
        )


def test_results_round_trip_through_json() -> None:
    solved = PlanResult(
        PlannerStatus.SOLVED, np.array([[0.0, 0.5], [1.0, -1.0]]), "ok", {"run_ms": 3.5}, seed=7
    )
    for result in (solved, PlanResult(PlannerStatus.TIMEOUT, message="budget spent")):
        back = result_from_message(json.loads(json.dumps(result_message(result))))
        assert (back.status, back.message, back.stats, back.seed) == (
            result.status,
            result.message,
            result.stats,
            result.seed,
        )
        if result.path is None:
            assert back.path is None
        else:
            assert back.path is not None and np.array_equal(back.path, result.path)


def test_a_scene_sent_parsed_travels_as_its_payload() -> None:
    parsed = parse_scene(PAYLOAD)
    sent = replace(problem(stored=False), scene=SceneSource.of(parsed))
    message = task_message(sent)
    assert message["scene"] == {"hash": parsed.hash, "payload": scene_to_payload(parsed)}
    assert parse_scene(message["scene"]["payload"]).hash == parsed.hash
