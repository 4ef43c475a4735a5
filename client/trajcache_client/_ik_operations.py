"""The IK and Cartesian path endpoints, natively and as MoveIt's GetPositionIK and
GetCartesianPath. Like `_operations`, one function per endpoint form."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any, cast

import httpx

from trajcache_client._models import CartesianResult, IkResult
from trajcache_client._moveit_models import GetCartesianPathResponse, GetPositionIKResponse
from trajcache_client._operations import Operation, _json_object, _reader, _segment


def ik(robot_id: str, request: Mapping[str, Any]) -> Operation[IkResult]:
    """POST /v1/robots/{robot_id}/ik: `{link, position, orientation, ...}` → the state nearest
    the seed that puts the link at the pose, or a status saying why there is none."""
    return Operation(
        "POST",
        f"/v1/robots/{_segment(robot_id)}/ik",
        _reader(IkResult),
        idempotent=True,  # no state changes: safe to retry
        json=dict(request),
    )


def get_position_ik(
    robot_id: str, request: Mapping[str, Any] | str
) -> Operation[GetPositionIKResponse]:
    """POST /v1/robots/{robot_id}/ik with MoveIt's GetPositionIK request (`{ik_request: ...}`,
    a mapping as JSON, text as YAML) → its response `{solution, error_code, trajcache}`."""
    content, media_type = _document(request)
    return Operation(
        "POST",
        f"/v1/robots/{_segment(robot_id)}/ik",
        _moveit_answer,
        idempotent=True,
        content=content,
        headers={"content-type": media_type},
    )


def cartesian_path(robot_id: str, request: Mapping[str, Any]) -> Operation[CartesianResult]:
    """POST /v1/robots/{robot_id}/cartesian-path: `{start, link, waypoints, max_step, ...}` →
    the joint path along the straight lines, as far as it goes (computed or from the cache)."""
    return Operation(
        "POST",
        f"/v1/robots/{_segment(robot_id)}/cartesian-path",
        _reader(CartesianResult),
        idempotent=True,  # a repeat is answered from the cache: safe to retry
        json=dict(request),
    )


def get_cartesian_path(
    robot_id: str, request: Mapping[str, Any] | str
) -> Operation[GetCartesianPathResponse]:
    """POST /v1/robots/{robot_id}/cartesian-path with MoveIt's GetCartesianPath request (a
    mapping as JSON, text as YAML) → `{start_state, solution, fraction, error_code, trajcache}`."""
    content, media_type = _document(request)
    return Operation(
        "POST",
        f"/v1/robots/{_segment(robot_id)}/cartesian-path",
        _cartesian_answer,
        idempotent=True,
        content=content,
        headers={"content-type": media_type},
    )


def _document(request: Mapping[str, Any] | str) -> tuple[bytes, str]:
    """A MoveIt request's body: a mapping as JSON, text as YAML."""
    if isinstance(request, Mapping):
        return json.dumps(request, allow_nan=False).encode(), "application/json"
    return request.encode(), "application/yaml"


def _moveit_answer(response: httpx.Response) -> GetPositionIKResponse:
    return cast(GetPositionIKResponse, _json_object(response))


def _cartesian_answer(response: httpx.Response) -> GetCartesianPathResponse:
    return cast(GetCartesianPathResponse, _json_object(response))
