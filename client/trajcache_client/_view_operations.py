"""The 3D view's endpoints (admin keys): a model's files and render geometry, stored scene
versions, and paths as link poses. Like `_operations`, one function per endpoint."""

from __future__ import annotations

from urllib.parse import quote

import httpx

from trajcache_client._operations import Operation, _query, _reader, _segment
from trajcache_client._view_models import ModelView, PathView, StoredScene


def _body(response: httpx.Response) -> bytes:
    return response.content


def get_model_file(model_id: str, path: str) -> Operation[bytes]:
    """GET /v1/robot-models/{model_id}/files/{path}: a file of the model's archive, as uploaded."""
    url = f"/v1/robot-models/{_segment(model_id)}/files/{quote(path, safe='/')}"
    return Operation("GET", url, _body, idempotent=True)


def get_scene_version(robot_id: str, version: int) -> Operation[StoredScene]:
    """GET /v1/robots/{robot_id}/scenes/{version}: any stored version of a robot's scene."""
    path = f"/v1/robots/{_segment(robot_id)}/scenes/{int(version)}"
    return Operation("GET", path, _reader(StoredScene), idempotent=True)


def get_scene_by_hash(scene_hash: str) -> Operation[StoredScene]:
    """GET /v1/scenes/{scene_hash}: the stored scene with this content hash."""
    path = f"/v1/scenes/{_segment(scene_hash)}"
    return Operation("GET", path, _reader(StoredScene), idempotent=True)


def model_view(model_id: str) -> Operation[ModelView]:
    """GET /v1/view/models/{model_id}: the model's links and collision geometry, for drawing."""
    path = f"/v1/view/models/{_segment(model_id)}"
    return Operation("GET", path, _reader(ModelView), idempotent=True)


def model_mesh(model_id: str, element: int) -> Operation[bytes]:
    """GET /v1/view/models/{model_id}/meshes/{element}: a mesh element's triangles, binary STL."""
    path = f"/v1/view/models/{_segment(model_id)}/meshes/{int(element)}"
    return Operation("GET", path, _body, idempotent=True)


def trajectory_view(trajectory_id: int, *, scene_hash: str | None = None) -> Operation[PathView]:
    """GET /v1/view/trajectories/{trajectory_id}: a stored trajectory as link poses."""
    path = f"/v1/view/trajectories/{int(trajectory_id)}"
    params = _query(scene_hash=scene_hash)
    return Operation("GET", path, _reader(PathView), idempotent=True, params=params)


def cartesian_path_view(path_id: int) -> Operation[PathView]:
    """GET /v1/view/cartesian-paths/{path_id}: a stored Cartesian path and its lines."""
    path = f"/v1/view/cartesian-paths/{int(path_id)}"
    return Operation("GET", path, _reader(PathView), idempotent=True)


def plan_event_view(event_id: int, *, candidate: int | None = None) -> Operation[PathView]:
    """GET /v1/view/plan-events/{event_id}: what a plan request validated, at its failure."""
    path = f"/v1/view/plan-events/{int(event_id)}"
    params = _query(candidate=candidate)
    return Operation("GET", path, _reader(PathView), idempotent=True, params=params)
