"""Schemathesis against the live app: every operation of openapi/openapi.json, no 5xx, and every
answer as the document declares it (status code, content type, body schema).

The app runs in a real uvicorn server on loopback (lifespan, migrations, planner pool) with API
key checks on; requests carry an admin key. A robot model, a robot with a scene, trajectories and
a seed job exist first, so path parameters hit real objects as well as unknown ones. Generation
is derandomized and bounded, so a run is repeatable and short.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest
import schemathesis
import uvicorn
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from hypothesis.errors import Unsatisfiable
from schemathesis import GenerationMode
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    negative_data_rejection,
    response_schema_conformance,
    status_code_conformance,
)

from tests.robots import TWO_JOINT_URDF
from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.main import create_app
from trajcache.services.catalog.keys import create_key
from trajcache.services.context import ServiceContext

DOCUMENT = Path(__file__).resolve().parents[2] / "openapi" / "openapi.json"
EXAMPLES = {GenerationMode.POSITIVE: 40, GenerationMode.NEGATIVE: 15}
NDJSON = "application/x-ndjson"
# Any bytes are text: a body "violating" a text schema is still valid text on the wire.
TEXT_BODIES = {"POST /v1/admin/import"}
# Answers that conform to the document; negative data must also be refused (4xx).
POSITIVE_CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_schema_conformance,
]
NEGATIVE_CHECKS = [*POSITIVE_CHECKS, negative_data_rejection]
ROBOT = "robot-1"
SCENE = {
    "objects": [
        {"id": "table", "type": "box", "size": [0.4, 0.4, 0.1], "pose": {"position": [0.6, 0, 0.2]}}
    ],
    "env": {"door": 0.5},
}
# Settings that keep random requests cheap: a small planner budget on one worker process, small
# seed jobs and pages; key checks on.
FUZZ_SETTINGS: dict[str, Any] = {
    "auth_mode": "on",
    "worker_processes": 1,
    "worker_prestart": False,
    "plan_budget_s": 0.1,
    "plan_budget_max_s": 0.3,
    "seed_max_queries": 20,
    "seed_max_scenes": 3,
    "seed_concurrency": 1,
    "max_page_size": 50,
    "negative_cache_ttl_s": 60.0,
}


@schemathesis.serializer(NDJSON)
def _ndjson(_ctx: schemathesis.SerializationContext, value: Any) -> bytes:
    """An import body: the generated text as it is."""
    return value if isinstance(value, bytes) else str(value).encode()


@dataclass(frozen=True)
class LiveApp:
    """A running server: its base URL, the admin key's headers and ids of stored objects."""

    base_url: str
    headers: dict[str, str]
    path_values: dict[str, list[Any]]
    export_lines: list[str]


def _serve(settings: Settings) -> Iterator[tuple[str, ServiceContext]]:
    app = create_app(settings)
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="on")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    wait_until(lambda: server.started or not thread.is_alive(), timeout_s=60)
    assert server.started, "the server did not start"
    try:
        yield f"http://127.0.0.1:{port}", app.state.ctx
    finally:
        server.should_exit = True
        thread.join(timeout=30)
        sock.close()


def _prepare(base_url: str, headers: dict[str, str]) -> dict[str, list[Any]]:
    """Store a model, a robot with a scene, trajectories and a seed job; their ids."""
    with httpx.Client(base_url=base_url, headers=headers, timeout=30) as http:

        def ok(response: httpx.Response) -> Any:
            assert response.status_code < 300, response.text
            return response.json() if response.content else None

        model_id = ok(http.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF}))["model_id"]
        ok(http.put(f"/v1/robots/{ROBOT}", json={"model_id": model_id}))
        scene = ok(http.put(f"/v1/robots/{ROBOT}/scene", json=SCENE))
        trajectories = [
            ok(http.post("/v1/trajectories", json={"model_id": model_id, "states": states}))
            for states in ([[0, 0], [0.5, 0.2]], [[-0.5, 0.1], [0.2, -0.3], [0.4, 0.4]])
        ]
        plan = {"start": [0.01, 0.0], "goal": [0.49, 0.2], "options": {"fallback": False}}
        ok(http.post(f"/v1/robots/{ROBOT}/plan", json=plan))
        job = ok(
            http.post(
                "/v1/seed-jobs",
                json={
                    "model_id": model_id,
                    "scenes": [SCENE],
                    "queries": [{"start": [0, 0], "goal": [0.3, 0.3]}],
                },
            )
        )
        events: list[Any] = []

        def recorded() -> bool:
            params = {"limit": 1, "robot_id": ROBOT}  # the hit, not the seed job's plans
            events[:] = ok(http.get("/v1/plan-events", params=params))["items"]
            return bool(events)

        assert wait_until(recorded, timeout_s=30, interval_s=0.05), "the plan left no event"
    return {
        "model_id": [model_id],
        "robot_id": [ROBOT],
        "trajectory_id": [t["trajectory_id"] for t in trajectories],
        "job_id": [job["job_id"]],
        "version": [scene["version"]],
        "scene_hash": [scene["hash"]],
        "event_id": [events[0]["event_id"]],
        "element": [0],
        "path": ["meshes/upper.stl"],  # the two-joint arm has no files: a 404
        "path_id": [1],  # no Cartesian path is stored: a 404
    }


@pytest.fixture
def live_app(database_url: str) -> Iterator[LiveApp]:
    """The app in uvicorn on loopback, with an admin key and stored objects."""
    settings = Settings(database_url=database_url, **FUZZ_SETTINGS)
    serving = _serve(settings)
    base_url, ctx = next(serving)
    try:
        with ctx.sessions() as session:
            _, secret = create_key(session=session, name="fuzz admin", role="admin")
        headers = {"Authorization": f"Bearer {secret}"}
        path_values = _prepare(base_url, headers)
        export = httpx.get(f"{base_url}/v1/admin/export", headers=headers, timeout=30)
        assert export.status_code == 200, export.text
        yield LiveApp(base_url, headers, path_values, export.text.splitlines())
    finally:
        serving.close()


def _state() -> st.SearchStrategy[list[float]]:
    """A state of the 2-joint robot, within its joint limits."""
    return st.lists(st.floats(-1.4, 1.4), min_size=2, max_size=2)


def _pose() -> st.SearchStrategy[dict[str, Any]]:
    return st.fixed_dictionaries({"position": st.lists(st.floats(-2, 2), min_size=3, max_size=3)})


def _scene_object() -> st.SearchStrategy[dict[str, Any]]:
    box = st.fixed_dictionaries(
        {"type": st.just("box"), "size": st.lists(st.floats(0.01, 1), min_size=3, max_size=3)}
    )
    sphere = st.fixed_dictionaries(
        {"type": st.just("sphere"), "size": st.lists(st.floats(0.01, 1), min_size=1, max_size=1)}
    )
    return st.builds(
        lambda shape, oid, pose: {"id": oid, **shape, "pose": pose},
        st.one_of(box, sphere),
        st.sampled_from(["table", "door", "cart", "shelf"]),
        _pose(),
    )


_ENV = st.dictionaries(st.sampled_from(["door", "lid"]), st.floats(-1, 1), max_size=2)


def _plan_body(live: LiveApp) -> st.SearchStrategy[Any]:
    options = st.fixed_dictionaries(
        {},
        optional={
            "fallback": st.booleans(),
            "lookup": st.booleans(),
            "match": st.sampled_from(["full", "arm"]),
            "quality": st.sampled_from(["basic", "full"]),
            "budget_s": st.floats(0.01, 0.3),
            "planner": st.sampled_from(["rrtconnect", "prm"]),
            "timing": st.just({"sample_period_s": 0.05}),
        },
    )
    return st.fixed_dictionaries({"start": _state(), "goal": _state(), "options": options})


def _model_body(live: LiveApp) -> st.SearchStrategy[Any]:
    limits = st.one_of(st.floats(0.1, 10), st.dictionaries(st.just("elbow"), st.floats(0.1, 10)))
    return st.fixed_dictionaries(
        {"urdf": st.just(TWO_JOINT_URDF)},
        optional={
            "base": st.sampled_from(["fixed", "planar"]),
            "joint_names": st.sampled_from([["shoulder"], ["shoulder", "elbow"], ["knee"]]),
            "acceleration_limits": limits,
            "jerk_limits": limits,
            "end_effector_link": st.sampled_from(["upper", "fore", "hand"]),
        },
    )


def _robot_body(live: LiveApp) -> st.SearchStrategy[Any]:
    return st.fixed_dictionaries(
        {"model_id": st.sampled_from(live.path_values["model_id"])},
        optional={"kind": st.sampled_from(["real", "sim"])},
    )


def _scene_body(live: LiveApp) -> st.SearchStrategy[Any]:
    return st.fixed_dictionaries(
        {"objects": st.lists(_scene_object(), max_size=3, unique_by=lambda o: o["id"])},
        optional={"env": _ENV},
    )


def _scene_patch_body(live: LiveApp) -> st.SearchStrategy[Any]:
    return st.fixed_dictionaries(
        {},
        optional={
            "upsert": st.lists(_scene_object(), max_size=2, unique_by=lambda o: o["id"]),
            "remove": st.lists(st.sampled_from(["table", "door", "cart"]), max_size=2),
            "env": st.dictionaries(st.sampled_from(["door", "lid"]), st.none() | st.floats(-1, 1)),
        },
    )


def _trajectory_body(live: LiveApp) -> st.SearchStrategy[Any]:
    return st.fixed_dictionaries(
        {
            "model_id": st.sampled_from(live.path_values["model_id"]),
            "states": st.lists(_state(), min_size=2, max_size=5),
        },
        optional={
            "source": st.sampled_from(["real", "sim", "import", "planner"]),
            "robot_id": st.just(ROBOT),
            "env": _ENV,
            "planning_time_ms": st.floats(0, 1000),
        },
    )


def _seed_job_body(live: LiveApp) -> st.SearchStrategy[Any]:
    query = st.fixed_dictionaries({"start": _state(), "goal": _state()})
    return st.fixed_dictionaries(
        {
            "model_id": st.sampled_from(live.path_values["model_id"]),
            "scenes": st.lists(_scene_body(live), min_size=1, max_size=2),
            "queries": st.lists(query, min_size=1, max_size=3),
            "options": st.just({"budget_s": 0.05}),
        }
    )


def _import_body(live: LiveApp) -> st.SearchStrategy[Any]:
    """Whole exports, which import, or exports with stray text, which a strict import refuses."""
    exported = st.sampled_from(live.export_lines)
    whole = st.lists(exported, min_size=1, max_size=6)
    stray = st.lists(exported | st.text(max_size=20), max_size=6)
    return st.builds("\n".join, whole | stray)


# Bodies the service can accept, for half of the positive cases: generated ones from the
# document alone rarely get past validation into the service code.
BODIES: dict[str, Callable[[LiveApp], st.SearchStrategy[Any]]] = {
    "PUT /v1/robots/{robot_id}": _robot_body,
    "POST /v1/robots/{robot_id}/plan": _plan_body,
    "POST /v1/robot-models": _model_body,
    "PUT /v1/robots/{robot_id}/scene": _scene_body,
    "PATCH /v1/robots/{robot_id}/scene": _scene_patch_body,
    "POST /v1/trajectories": _trajectory_body,
    "POST /v1/seed-jobs": _seed_job_body,
    "POST /v1/admin/import": _import_body,
}


def _fuzz(operation: Any, mode: GenerationMode, live: LiveApp, statuses: Counter[int]) -> None:
    positive = mode is GenerationMode.POSITIVE
    checks = POSITIVE_CHECKS if positive else NEGATIVE_CHECKS
    if operation.label in TEXT_BODIES:
        checks = POSITIVE_CHECKS
    body_fn = BODIES.get(operation.label) if positive else None
    bodies = body_fn(live) if body_fn is not None else st.nothing()

    @settings(
        max_examples=EXAMPLES[mode],
        derandomize=True,
        database=None,
        deadline=None,
        phases=[Phase.explicit, Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(case=operation.as_strategy(generation_mode=mode), data=st.data())
    def run(case: Any, data: st.DataObject) -> None:
        if positive and case.path_parameters and data.draw(st.integers(0, 2)) > 0:
            for name in case.path_parameters:  # two thirds name stored objects
                case.path_parameters[name] = data.draw(st.sampled_from(live.path_values[name]))
        if body_fn is not None and data.draw(st.booleans()):
            case.body = data.draw(bodies)
        response = case.call_and_validate(
            base_url=live.base_url, headers=live.headers, checks=checks, timeout=30
        )
        statuses[response.status_code] += 1

    with contextlib.suppress(Unsatisfiable):  # negative mode: no parameter can be invalid
        run()


# Operations some fuzzed request must get through (2xx) with.
REACHED = [
    *BODIES,
    "GET /v1/trajectories/{trajectory_id}",
    "GET /v1/seed-jobs/{job_id}",
    "GET /v1/robots/{robot_id}/scenes/{version}",
    "GET /v1/scenes/{scene_hash}",
    "GET /v1/view/models/{model_id}",
    "GET /v1/view/trajectories/{trajectory_id}",
    "GET /v1/view/plan-events/{event_id}",
]


def _operations() -> list[Any]:
    """Every operation, the views first: later ones delete and prune what they show."""
    schema = schemathesis.openapi.from_path(DOCUMENT)
    operations = [result.ok() for result in schema.get_all_operations()]
    return sorted(operations, key=lambda op: not op.label.startswith("GET /v1/view/"))


def test_every_operation_answers_as_documented(live_app: LiveApp) -> None:
    operations = _operations()
    assert len(operations) >= 20
    statuses: dict[str, Counter[int]] = {op.label: Counter() for op in operations}
    failures: list[str] = []
    began = time.monotonic()
    for operation in operations:
        for mode in EXAMPLES:
            try:
                _fuzz(operation, mode, live_app, statuses[operation.label])
            except (Exception, BaseExceptionGroup) as exc:  # a FailureGroup is the latter
                failures.append(f"{operation.label} ({mode.value}):\n{exc}")
    elapsed = time.monotonic() - began
    for label, counts in statuses.items():
        print(f"{label}: {dict(sorted(counts.items()))}")
    total = sum(sum(c.values()) for c in statuses.values())
    print(f"fuzzed {len(operations)} operations with {total} requests in {elapsed:.1f} s")
    assert not failures, "\n\n".join(failures)
    # The fuzzing got past validation into the service, the planner included.
    unreached = [op for op in REACHED if not any(200 <= c < 300 for c in statuses[op])]
    assert not unreached, f"no request was accepted by {unreached}"
    planned = httpx.get(
        f"{live_app.base_url}/v1/plan-events",
        params={"source": "planner", "limit": 1},
        headers=live_app.headers,
    )
    assert planned.status_code == 200 and planned.json()["items"], planned.text
