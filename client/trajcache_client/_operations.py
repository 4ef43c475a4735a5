"""One function per endpoint: the request to send and how to read its answer.

`Client` and `AsyncClient` call these, so an endpoint is described once; adding one is a
function here and a one-line method on each client.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar
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
    RobotModel,
    RobotModelDetail,
    RobotModelSummary,
    Scene,
    SceneVersion,
    Trajectory,
    TrajectoryCreated,
    TrajectorySummary,
)

T = TypeVar("T")
M = TypeVar("M", bound=pydantic.BaseModel)

StateLike = Iterable[float]
"""A state as numbers ordered as the model's `state_names` (a list, tuple or numpy array)."""


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


def _no_content(response: httpx.Response) -> None:
    return None


def _segment(value: str | int) -> str:
    return quote(str(value), safe="")


def _state(values: StateLike) -> list[float]:
    return [float(v) for v in values]


def _query(**params: Any) -> dict[str, Any]:
    return {k: v for k, v in params.items() if v is not None}


# --- robot models ---------------------------------------------------------------------------


def register_model(
    urdf: str,
    *,
    base: str = "fixed",
    joint_names: Sequence[str] | None = None,
    name: str | None = None,
    archive: bytes | Path | None = None,
    archive_name: str = "meshes.zip",
) -> Operation[RobotModel]:
    """POST /v1/robot-models: JSON, or multipart/form-data when a mesh archive is attached."""
    read = _reader(RobotModel)
    if archive is None:
        body: dict[str, Any] = {"urdf": urdf, "base": base}
        if joint_names is not None:
            body["joint_names"] = list(joint_names)
        if name is not None:
            body["name"] = name
        return Operation("POST", "/v1/robot-models", read, idempotent=True, json=body)
    if isinstance(archive, Path):
        archive_name, archive = archive.name, archive.read_bytes()
    fields = {"urdf": urdf, "base": base}
    if joint_names is not None:
        fields["joint_names"] = ",".join(joint_names)
    if name is not None:
        fields["name"] = name
    files = {"archive": (archive_name, archive, "application/octet-stream")}
    # Registration is content-addressed: sending it twice registers one model.
    return Operation("POST", "/v1/robot-models", read, idempotent=True, data=fields, files=files)


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


def put_robot(robot_id: str, model_id: str) -> Operation[Robot]:
    """PUT /v1/robots/{robot_id}."""
    path = f"/v1/robots/{_segment(robot_id)}"
    return Operation("PUT", path, _reader(Robot), idempotent=True, json={"model_id": model_id})


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
    goal: StateLike,
    options: PlanOptions | Mapping[str, Any] | None = None,
) -> Operation[PlanResult]:
    """POST /v1/robots/{robot_id}/plan; the read timeout covers the planning budget asked for."""
    if options is None:
        options = PlanOptions()
    elif not isinstance(options, PlanOptions):
        options = PlanOptions.model_validate(dict(options))
    body = {
        "start": _state(start),
        "goal": _state(goal),
        "options": options.model_dump(exclude_none=True),
    }
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


# --- trajectories ---------------------------------------------------------------------------


def store_trajectory(
    model_id: str,
    states: Iterable[StateLike],
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
        states=[_state(s) for s in states],
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
