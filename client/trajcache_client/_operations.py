"""One function per endpoint: the request to send and how to read its answer.

`Client` and `AsyncClient` call these, so an endpoint is described once; adding one is a
function here and one line in `_endpoints.Endpoints`, which makes it a method of both.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar, cast
from urllib.parse import quote

import httpx
import pydantic

from trajcache_client._exceptions import UnexpectedResponseError
from trajcache_client._models import (
    Health,
    Page,
    PlanOptions,
    PlanResult,
    Robot,
    RobotKind,
    RobotModel,
    RobotModelDetail,
    RobotModelSummary,
    Scene,
    SceneVersion,
    Trajectory,
    TrajectoryCreated,
    TrajectorySummary,
)
from trajcache_client._moveit_models import MotionPlanResponse

T = TypeVar("T")
M = TypeVar("M", bound=pydantic.BaseModel)

StateValues = Iterable[float]
"""A state as numbers ordered as the model's `state_names` (a list, tuple or numpy array)."""

StateLike = StateValues | Mapping[str, float] | str
"""A plan's start or goal: values in `state_names` order, a {joint name: value} map, or the
name of one of the model's named states (an SRDF group_state)."""

JointLimits = float | Mapping[str, float]
"""One limit for every planning joint, or limits by joint name."""


@dataclass(frozen=True)
class Operation(Generic[T]):
    """A request and the function that reads its answer."""

    method: str
    path: str
    read: Callable[[httpx.Response], T]
    idempotent: bool
    params: Mapping[str, Any] | None = None
    json: Any = None
    content: bytes | None = None
    data: Mapping[str, str] | None = None
    files: Mapping[str, tuple[str, bytes, str]] | None = None
    headers: Mapping[str, str] | None = None
    retry: bool = True
    read_timeout_s: float | None = None  # at least this long to read the answer


def _reader(model: type[M]) -> Callable[[httpx.Response], M]:
    def read(response: httpx.Response) -> M:
        try:
            return model.model_validate_json(response.content)
        except pydantic.ValidationError as exc:
            raise UnexpectedResponseError(
                f"{response.request.method} {response.request.url.path} answered a body that is "
                f"not a {model.__name__}: {exc}",
                response=response,
            ) from exc

    return read


def _json_object(response: httpx.Response) -> dict[str, Any]:
    try:
        body = response.json()
    except ValueError:
        body = None
    if not isinstance(body, dict):
        raise UnexpectedResponseError(
            f"{response.request.method} {response.request.url.path} answered a body that is "
            "not a JSON object",
            response=response,
        )
    return body


def _motion_plan_response(response: httpx.Response) -> MotionPlanResponse:
    return cast(MotionPlanResponse, _json_object(response))


def _no_content(response: httpx.Response) -> None:
    return None


def _segment(value: str | int) -> str:
    return quote(str(value), safe="")


def _values(values: StateValues) -> list[float]:
    return [float(v) for v in values]


def _by_name(values: Mapping[str, float]) -> dict[str, float]:
    return {str(name): float(value) for name, value in values.items()}


def _state(state: StateLike) -> list[float] | dict[str, float] | str:
    # A str and a Mapping are iterable too: test them first.
    if isinstance(state, str):
        return state
    if isinstance(state, Mapping):
        return _by_name(state)
    return _values(state)


def _held(values: Mapping[str, float] | str | None) -> dict[str, float] | str | None:
    if values is None or isinstance(values, str):
        return values  # a str names an SRDF group_state
    return _by_name(values)


def _limits(limits: JointLimits | None) -> float | dict[str, float] | None:
    if limits is None:
        return None
    return _by_name(limits) if isinstance(limits, Mapping) else float(limits)


def _form_text(value: Any) -> str:
    """A registration field as multipart text: names comma-separated, numbers and maps as JSON."""
    if isinstance(value, str):
        return value
    if isinstance(value, list):
        return ",".join(value)
    return json.dumps(value, allow_nan=False)


def _query(**params: Any) -> dict[str, Any]:
    return {k: v for k, v in params.items() if v is not None}


# --- robot models ---------------------------------------------------------------------------


def register_model(
    urdf: str,
    *,
    srdf: str | None = None,
    group: str | None = None,
    joint_values: Mapping[str, float] | str | None = None,
    base: str = "fixed",
    joint_names: Sequence[str] | None = None,
    name: str | None = None,
    archive: bytes | Path | None = None,
    archive_name: str = "meshes.zip",
    acceleration_limits: JointLimits | None = None,
    jerk_limits: JointLimits | None = None,
    end_effector_link: str | None = None,
) -> Operation[RobotModel]:
    """POST /v1/robot-models: JSON, or multipart/form-data when a mesh archive is attached."""
    read = _reader(RobotModel)
    fields = _query(
        urdf=urdf,
        srdf=srdf,
        base=base,
        joint_names=None if joint_names is None else list(joint_names),
        group=group,
        joint_values=_held(joint_values),
        name=name,
        acceleration_limits=_limits(acceleration_limits),
        jerk_limits=_limits(jerk_limits),
        end_effector_link=end_effector_link,
    )
    # Registration is content-addressed: sending it twice registers one model.
    if archive is None:
        return Operation("POST", "/v1/robot-models", read, idempotent=True, json=fields)
    if isinstance(archive, Path):
        archive_name, archive = archive.name, archive.read_bytes()
    files = {"archive": (archive_name, archive, "application/octet-stream")}
    if srdf is not None:
        files["srdf"] = ("robot.srdf", fields.pop("srdf").encode(), "application/xml")
    data = {key: _form_text(value) for key, value in fields.items()}
    return Operation("POST", "/v1/robot-models", read, idempotent=True, data=data, files=files)


def list_models(*, limit: int | None = None, offset: int = 0) -> Operation[Page[RobotModelSummary]]:
    """GET /v1/robot-models."""
    params = _query(limit=limit, offset=offset)
    return Operation(
        "GET", "/v1/robot-models", _reader(Page[RobotModelSummary]), idempotent=True, params=params
    )


def get_model(model_id: str) -> Operation[RobotModelDetail]:
    """GET /v1/robot-models/{model_id}."""
    path = f"/v1/robot-models/{_segment(model_id)}"
    return Operation("GET", path, _reader(RobotModelDetail), idempotent=True)


# --- robots and scenes ----------------------------------------------------------------------


def put_robot(
    robot_id: str,
    model_id: str,
    *,
    kind: RobotKind | None = None,
    joint_values: Mapping[str, float] | None = None,
) -> Operation[Robot]:
    """PUT /v1/robots/{robot_id}; None keeps the robot's kind or held values, {} resets them."""
    body = _query(
        model_id=model_id,
        kind=kind,
        joint_values=None if joint_values is None else _by_name(joint_values),
    )
    path = f"/v1/robots/{_segment(robot_id)}"
    return Operation("PUT", path, _reader(Robot), idempotent=True, json=body)


def get_robot(robot_id: str) -> Operation[Robot]:
    """GET /v1/robots/{robot_id}."""
    return Operation("GET", f"/v1/robots/{_segment(robot_id)}", _reader(Robot), idempotent=True)


def put_scene(
    robot_id: str, scene: Mapping[str, Any] | str | bytes, *, media_type: str | None = None
) -> Operation[SceneVersion]:
    """PUT /v1/robots/{robot_id}/scene: a mapping goes as JSON, text as YAML unless told."""
    if isinstance(scene, Mapping):
        content = json.dumps(scene, allow_nan=False).encode()
        media_type = media_type or "application/json"
    else:
        content = scene.encode() if isinstance(scene, str) else bytes(scene)
        media_type = media_type or "application/yaml"
    path = f"/v1/robots/{_segment(robot_id)}/scene"
    headers = {"content-type": media_type}
    return Operation(
        "PUT", path, _reader(SceneVersion), idempotent=True, content=content, headers=headers
    )


def patch_scene(
    robot_id: str,
    *,
    upsert: Sequence[Mapping[str, Any]] = (),
    remove: Sequence[str] = (),
    env: Mapping[str, float | None] | None = None,
) -> Operation[SceneVersion]:
    """PATCH /v1/robots/{robot_id}/scene (not retried but on 503: a removal may not repeat)."""
    body = {"upsert": [dict(o) for o in upsert], "remove": list(remove), "env": dict(env or {})}
    path = f"/v1/robots/{_segment(robot_id)}/scene"
    return Operation("PATCH", path, _reader(SceneVersion), idempotent=False, json=body)


def get_scene(robot_id: str) -> Operation[Scene]:
    """GET /v1/robots/{robot_id}/scene."""
    path = f"/v1/robots/{_segment(robot_id)}/scene"
    return Operation("GET", path, _reader(Scene), idempotent=True)


# --- planning -------------------------------------------------------------------------------


def plan(
    robot_id: str,
    start: StateLike,
    goal: StateLike | None,
    options: PlanOptions | Mapping[str, Any] | None = None,
    *,
    goal_pose: Mapping[str, Any] | None = None,
) -> Operation[PlanResult]:
    """POST /v1/robots/{robot_id}/plan; the goal is a state, or (goal None) `goal_pose`: a
    link's pose {link, position, orientation, position_tolerance, orientation_tolerance}. The
    read timeout covers the planning budget asked for."""
    if options is None:
        options = PlanOptions()
    elif not isinstance(options, PlanOptions):
        options = PlanOptions.model_validate(dict(options))
    body: dict[str, Any] = {
        "start": _state(start),
        "options": options.model_dump(exclude_none=True),
    }
    if goal is not None:
        body["goal"] = _state(goal)
    if goal_pose is not None:
        body["goal_pose"] = dict(goal_pose)
    path = f"/v1/robots/{_segment(robot_id)}/plan"
    budget = options.budget_s
    return Operation(
        "POST",
        path,
        _reader(PlanResult),
        idempotent=False,
        json=body,
        read_timeout_s=None if budget is None else budget + 10.0,
    )


def motion_plan(robot_id: str, request: Mapping[str, Any] | str) -> Operation[MotionPlanResponse]:
    """POST /v1/robots/{robot_id}/motion-plan: a MoveIt MotionPlanRequest (a mapping as JSON,
    text as YAML) → its MotionPlanResponse; retried like `plan`, waiting for its planning time."""
    if isinstance(request, Mapping):
        content = json.dumps(request, allow_nan=False).encode()
        media_type = "application/json"
    else:
        content, media_type = request.encode(), "application/yaml"
    budget = _allowed_planning_time(request)
    return Operation(
        "POST",
        f"/v1/robots/{_segment(robot_id)}/motion-plan",
        _motion_plan_response,
        idempotent=False,
        content=content,
        headers={"content-type": media_type},
        read_timeout_s=None if budget is None else budget + 10.0,
    )


def _allowed_planning_time(request: Mapping[str, Any] | str) -> float | None:
    """The request's planning budget, bare or wrapped as GetMotionPlan or MoveGroup wrap it."""
    if isinstance(request, str):
        return None  # YAML is left to the service to read
    message = request.get("motion_plan_request", request.get("request", request))
    budget = message.get("allowed_planning_time") if isinstance(message, Mapping) else None
    if isinstance(budget, bool) or not isinstance(budget, int | float) or budget <= 0:
        return None  # 0 or none: the service's default budget
    return float(budget)


# --- trajectories ---------------------------------------------------------------------------


def store_trajectory(
    model_id: str,
    states: Iterable[StateValues],
    *,
    source: str = "real",
    robot_id: str | None = None,
    scene_hash: str | None = None,
    env: Mapping[str, float] | None = None,
    planning_time_ms: float | None = None,
) -> Operation[TrajectoryCreated]:
    """POST /v1/trajectories (an identical trajectory is stored once, so it may be retried)."""
    body = _query(
        model_id=model_id,
        states=[_values(s) for s in states],
        source=source,
        robot_id=robot_id,
        scene_hash=scene_hash,
        env=dict(env) if env is not None else None,
        planning_time_ms=planning_time_ms,
    )
    return Operation(
        "POST", "/v1/trajectories", _reader(TrajectoryCreated), idempotent=True, json=body
    )


def list_trajectories(
    *,
    model_id: str | None = None,
    source: str | None = None,
    robot_id: str | None = None,
    limit: int | None = None,
    offset: int = 0,
) -> Operation[Page[TrajectorySummary]]:
    """GET /v1/trajectories, filtered by model, source and robot."""
    params = _query(model_id=model_id, source=source, robot_id=robot_id, limit=limit, offset=offset)
    return Operation(
        "GET", "/v1/trajectories", _reader(Page[TrajectorySummary]), idempotent=True, params=params
    )


def get_trajectory(trajectory_id: int) -> Operation[Trajectory]:
    """GET /v1/trajectories/{trajectory_id}."""
    path = f"/v1/trajectories/{_segment(trajectory_id)}"
    return Operation("GET", path, _reader(Trajectory), idempotent=True)


def delete_trajectory(trajectory_id: int) -> Operation[None]:
    """DELETE /v1/trajectories/{trajectory_id}."""
    path = f"/v1/trajectories/{_segment(trajectory_id)}"
    return Operation("DELETE", path, _no_content, idempotent=True)


# --- health ---------------------------------------------------------------------------------


def health() -> Operation[Health]:
    """GET /healthz: the process answers."""
    return Operation("GET", "/healthz", _reader(Health), idempotent=True, retry=False)


def ready() -> Operation[Health]:
    """GET /readyz: the database answers (a 503 raises UnavailableError, without retries)."""
    return Operation("GET", "/readyz", _reader(Health), idempotent=True, retry=False)
