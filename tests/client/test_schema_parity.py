"""The client mirrors openapi/openapi.json: a model per schema with the same fields, required-ness
and types, and an operation (and a method on both clients) per /v1 path and method."""

from __future__ import annotations

import datetime
import functools
import inspect
import json
import re
import types
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal, Union, get_args, get_origin, is_typeddict

import pydantic
import pytest

import trajcache_client as tc
from tests.robots import OPAQUE_URDF
from trajcache_client import (
    _admin_operations,
    _ik_operations,
    _moveit_models,
    _operations,
    _view_operations,
)
from trajcache_client._operations import Operation

DOCUMENT = Path(__file__).resolve().parents[2] / "openapi" / "openapi.json"

# Each client model and the schema component it mirrors.
MODELS: dict[Any, str] = {
    tc.RobotModel: "RobotModelOut",
    tc.RobotModelSummary: "RobotModelSummary",
    tc.RobotModelDetail: "RobotModelDetail",
    tc.Page[tc.RobotModelSummary]: "RobotModelPage",
    tc.ModelFile: "ModelFileOut",
    tc.SkippedPair: "SkippedPairOut",
    tc.Robot: "RobotOut",
    tc.SceneVersion: "SceneVersionOut",
    tc.Scene: "SceneOut",
    tc.PlanOptions: "PlanOptions",
    tc.TimingOptions: "TimingOptions",
    tc.PlanResult: "PlanResponse",
    tc.IkResult: "IkResponse",
    tc.CartesianResult: "CartesianResponse",
    tc.Rejection: "Rejection",
    tc.ValidationReuse: "ValidationReuse",
    tc.RejectedCandidate: "RejectedCandidateOut",
    tc.ContactPair: "ContactPairOut",
    tc.TrajectoryQuality: "TrajectoryQuality",
    tc.JointTrajectory: "JointTrajectory",
    tc.JointTrajectoryPoint: "JointTrajectoryPoint",
    tc.TrajectoryCreated: "TrajectoryCreated",
    tc.TrajectorySummary: "TrajectorySummary",
    tc.Page[tc.TrajectorySummary]: "TrajectoryPage",
    tc.Trajectory: "TrajectoryDetailOut",
    tc.PlanEvent: "PlanEventOut",
    tc.PlanEventPage: "PlanEventPageOut",
    tc.Stats: "StatsOut",
    tc.Metrics: "MetricsOut",
    tc.Latency: "LatencyOut",
    tc.StatsGroup: "GroupOut",
    tc.StatsBucket: "BucketOut",
    tc.ModelBasis: "ModelBasisOut",
    tc.TopTrajectory: "TopTrajectoryOut",
    tc.SeedJob: "SeedJobOut",
    tc.SeedJobError: "SeedJobError",
    tc.Page[tc.SeedJob]: "SeedJobPage",
    tc.PruneResult: "PruneOut",
    tc.ModelPrune: "ModelPruneOut",
    tc.ImportResult: "ImportOut",
    tc.RejectedLine: "RejectedLineOut",
    tc.Health: "HealthOut",
    tc.MotionPlanResponse: "MotionPlanResponseOut",
    _moveit_models.RobotState: "RobotStateOut",
    _moveit_models.JointState: "JointStateOut",
    _moveit_models.MultiDOFJointState: "MultiDOFJointStateOut",
    _moveit_models.Transform: "TransformOut",
    _moveit_models.Vector3: "Vector3Out",
    _moveit_models.Quaternion: "QuaternionOut",
    _moveit_models.Twist: "TwistOut",
    _moveit_models.Duration: "DurationOut",
    _moveit_models.RobotTrajectory: "RobotTrajectoryOut",
    _moveit_models.MoveItJointTrajectory: "JointTrajectoryOut",
    _moveit_models.MoveItJointTrajectoryPoint: "JointTrajectoryPointOut",
    _moveit_models.MultiDOFJointTrajectory: "MultiDOFJointTrajectoryOut",
    _moveit_models.MultiDOFJointTrajectoryPoint: "MultiDOFJointTrajectoryPointOut",
    _moveit_models.MoveItErrorCode: "ErrorCodeOut",
    _moveit_models.TrajcacheExtras: "TrajcacheExtrasOut",
    _moveit_models.CandidateRejection: "CandidateRejectionOut",
    _moveit_models.GetPositionIKResponse: "GetPositionIKOut",
    _moveit_models.TrajcacheIkExtras: "TrajcacheIkOut",
    _moveit_models.GetCartesianPathResponse: "GetCartesianPathOut",
    _moveit_models.TrajcacheCartesianExtras: "TrajcacheCartesianOut",
    tc.ModelView: "ModelViewOut",
    tc.ModelElement: "ModelElementOut",
    tc.StoredScene: "StoredSceneOut",
    tc.PathView: "PathViewOut",
    tc.Frames: "FramesOut",
    tc.Failure: "FailureOut",
    tc.GoalPose: "GoalPoseOut",
    tc.CartesianLines: "CartesianLinesOut",
}
# Request bodies the client builds: None there means "leave it to the service" (not sent).
REQUESTS = {tc.PlanOptions, tc.TimingOptions}
# Fields the service always sends but older services did not: read with a default.
ADDED_LATER = {
    ("TrajectoryQuality", "ee_path_length"),
    ("TrajectoryQuality", "min_clearance"),
    ("TrajectoryQuality", "duration_s"),
    ("TrajectoryDetailOut", "usage_history"),
    ("PlanEventOut", "requester"),
    ("SeedJobOut", "stored"),
}
# Read from `detail` and `errors` by the exception classes, not as a model.
ERROR_BODIES = {"ErrorOut", "FieldErrorOut"}
_SCALARS = {"integer": "int", "number": "float", "boolean": "bool", "null": "None"}
_PY_SCALARS = {int: "int", float: "float", bool: "bool", str: "str", type(None): "None"}


@functools.cache
def _document() -> dict[str, Any]:
    loaded: dict[str, Any] = json.loads(DOCUMENT.read_text(encoding="utf-8"))
    return loaded


def _schemas() -> dict[str, Any]:
    schemas: dict[str, Any] = _document()["components"]["schemas"]
    return schemas


def _name(model: Any) -> str:
    return str(model.__name__)


def _client_names() -> dict[str, str]:
    """Schema component → the name of the client type that mirrors it."""
    return {component: _name(model) for model, component in MODELS.items()}


def _union(members: list[str]) -> str:
    unique = sorted(set(members), key=lambda m: (m == "None", m))
    return " | ".join(unique)


def schema_type(schema: dict[str, Any] | bool) -> str:
    """A JSON schema as the Python annotation the client should use, written canonically."""
    if schema is True or schema == {}:
        return "Any"
    assert isinstance(schema, dict)
    if "$ref" in schema:
        component = schema["$ref"].rsplit("/", 1)[-1]
        return _client_names().get(component, f"<no client model of {component}>")
    if "anyOf" in schema:
        return _union([schema_type(s) for s in schema["anyOf"]])
    if "enum" in schema:
        return f"Literal[{', '.join(repr(v) for v in sorted(schema['enum']))}]"
    kind = schema.get("type")
    if kind == "string":
        return "datetime" if schema.get("format") == "date-time" else "str"
    if kind == "array":
        if "prefixItems" in schema:
            return f"tuple[{', '.join(schema_type(s) for s in schema['prefixItems'])}]"
        return f"list[{schema_type(schema.get('items', {}))}]"
    if kind == "object":
        return f"dict[str, {schema_type(schema.get('additionalProperties', {}))}]"
    return _SCALARS[str(kind)]


def client_type(annotation: Any) -> str:
    """A client annotation written canonically; `Literal[...] | str` (newer values kept as text)
    reads as the Literal."""
    origin, args = get_origin(annotation), get_args(annotation)
    if annotation is Any:
        return "Any"
    if annotation in _PY_SCALARS:
        return _PY_SCALARS[annotation]
    if annotation is datetime.datetime:
        return "datetime"
    if origin in (Union, types.UnionType):
        members = [client_type(a) for a in args]
        if any(m.startswith("Literal[") for m in members):
            members = [m for m in members if m != "str"]
        return _union(members)
    if origin is Literal:
        return f"Literal[{', '.join(repr(v) for v in sorted(args))}]"
    if origin in (list, tuple, dict):
        return f"{origin.__name__}[{', '.join(client_type(a) for a in args)}]"
    return _name(annotation)


def client_fields(model: Any) -> dict[str, tuple[str, bool]]:
    """Field → (canonical type, required) of a pydantic model or a TypedDict."""
    if is_typeddict(model):
        hints = typing.get_type_hints(model)
        return {k: (client_type(t), k in model.__required_keys__) for k, t in hints.items()}
    assert issubclass(model, pydantic.BaseModel)
    return {
        name: (client_type(field.annotation), field.is_required())
        for name, field in model.model_fields.items()
    }


def _cases() -> list[Any]:
    return [pytest.param(m, c, id=c) for m, c in MODELS.items()]


@pytest.mark.parametrize(("model", "component"), _cases())
def test_each_client_model_mirrors_its_schema(model: Any, component: str) -> None:
    schema = _schemas()[component]
    required = set(schema.get("required", ()))
    expected = {name: schema_type(s) for name, s in schema["properties"].items()}
    fields = client_fields(model)
    differ = set(fields) ^ set(expected)
    assert not differ, f"{_name(model)} and {component} differ in {sorted(differ)}"
    for name, (annotation, is_required) in fields.items():
        want = expected[name]
        if model in REQUESTS and "None" not in want:
            want = _union([*want.split(" | "), "None"])  # None: not sent
        assert annotation == want, f"{_name(model)}.{name}: {annotation} is not {want}"
        if name not in required:
            assert not is_required, f"{_name(model)}.{name} is optional in {component}"
        elif (component, name) not in ADDED_LATER:
            assert is_required, f"{_name(model)}.{name} is required in {component}"


def _refs(schema: Any) -> set[str]:
    """The components `schema` names, directly or through other components."""
    found: set[str] = set()
    todo = [schema]
    while todo:
        node = todo.pop()
        if isinstance(node, dict):
            ref = node.get("$ref")
            if isinstance(ref, str) and ref.rsplit("/", 1)[-1] not in found:
                found.add(ref.rsplit("/", 1)[-1])
                todo.append(_schemas()[ref.rsplit("/", 1)[-1]])
            todo.extend(node.values())
        elif isinstance(node, list):
            todo.extend(node)
    return found


def test_every_answer_schema_has_a_client_model() -> None:
    answered: set[str] = set()
    for methods in _document()["paths"].values():
        for op in methods.values():
            for code, response in op["responses"].items():
                if code.startswith("2"):
                    answered |= _refs(response.get("content", {}))
    assert answered - ERROR_BODIES - set(MODELS.values()) == set()


# --- operations -----------------------------------------------------------------------------

SAMPLES: dict[str, Any] = {
    "robot_id": "r1",
    "model_id": "m1",
    "trajectory_id": 7,
    "job_id": 7,
    "urdf": OPAQUE_URDF,
    "start": [0.0],
    "goal": [0.0],
    "scene": {},
    "request": {},
    "states": [[0.0], [1.0]],
    "spec": {},
    "data": b"",
    "path": "a.stl",
    "version": 1,
    "scene_hash": "0" * 64,
    "element": 0,
    "event_id": 7,
    "path_id": 12,
}
MODULES = (_operations, _admin_operations, _view_operations, _ik_operations)


def _operation_functions() -> dict[str, Callable[..., Operation[Any]]]:
    found = {}
    for module in MODULES:
        for name, fn in inspect.getmembers(module, inspect.isfunction):
            if fn.__module__ == module.__name__ and not name.startswith("_"):
                found[name] = fn
    return found


def _built(fn: Callable[..., Operation[Any]]) -> Operation[Any]:
    required = [
        p.name
        for p in inspect.signature(fn).parameters.values()
        if p.default is inspect.Parameter.empty and p.kind is p.POSITIONAL_OR_KEYWORD
    ]
    return fn(*(SAMPLES[name] for name in required))


def _template(path: str) -> re.Pattern[str]:
    return re.compile("^" + re.sub(r"\\\{[a-z_]+\\\}", "[^/]+", re.escape(path)) + "$")


def _client_operations() -> set[tuple[str, str]]:
    """(METHOD, path template) of every operation the client builds."""
    templates = [(m.upper(), p) for p, ops in _document()["paths"].items() for m in ops]
    covered = set()
    for fn in _operation_functions().values():
        op = _built(fn)
        matches = [(m, p) for m, p in templates if m == op.method and _template(p).match(op.path)]
        assert matches, f"{fn.__name__} sends {op.method} {op.path}, which is not in the API"
        covered |= set(matches)
    return covered


def test_every_v1_operation_has_a_client_operation() -> None:
    wanted = {
        (m.upper(), p) for p, ops in _document()["paths"].items() for m in ops if p[:4] == "/v1/"
    }
    assert wanted - _client_operations() == set()


@pytest.mark.parametrize("name", sorted(_operation_functions()))
def test_each_operation_is_a_method_of_both_clients(name: str) -> None:
    assert callable(getattr(tc.Client, name, None)), f"Client has no {name}"
    assert inspect.iscoroutinefunction(getattr(tc.AsyncClient, name, None)), name
    fn = _operation_functions()[name]
    assert fn.__doc__ and getattr(tc.Client, name).__doc__, name
