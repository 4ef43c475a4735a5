"""The IK endpoint, natively and as MoveIt's GetPositionIK. Like `_operations`, one function
per endpoint form."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any, cast

import httpx

from trajcache_client._models import IkResult
from trajcache_client._moveit_models import GetPositionIKResponse
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
    if isinstance(request, Mapping):
        content = json.dumps(request, allow_nan=False).encode()
        media_type = "application/json"
    else:
        content, media_type = request.encode(), "application/yaml"
    return Operation(
        "POST",
        f"/v1/robots/{_segment(robot_id)}/ik",
        _moveit_answer,
        idempotent=True,
        content=content,
        headers={"content-type": media_type},
    )


def _moveit_answer(response: httpx.Response) -> GetPositionIKResponse:
    return cast(GetPositionIKResponse, _json_object(response))
