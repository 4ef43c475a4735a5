"""/v1/robots: create or re-point robots; replace, patch and read their scenes."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Request, Response
from starlette.exceptions import HTTPException

from trajcache.api.deps import CtxDep, SessionDep, SettingsDep
from trajcache.api.schemas import (
    RobotIn,
    RobotOut,
    SceneIn,
    SceneOut,
    ScenePatchIn,
    SceneVersionOut,
)
from trajcache.db import models as tables
from trajcache.geometry.errors import SceneError
from trajcache.geometry.scene import Scene, parse_scene, parse_scene_text
from trajcache.services.errors import PayloadTooLargeError
from trajcache.services.robots import get_robot, get_scene, patch_scene, put_robot, put_scene

router = APIRouter(prefix="/robots", tags=["robots"])

JSON_TYPES = frozenset({"", "application/json"})
YAML_TYPES = frozenset(
    {"application/yaml", "application/x-yaml", "text/yaml", "text/x-yaml", "text/plain"}
)  # text: YAML or JSON
_SCENE_BODY: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": SceneIn.model_json_schema()},
            "application/yaml": {"schema": {"type": "string"}},
        },
    }
}
_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"description": "Unknown robot"}}


def _robot_out(robot: tables.Robot) -> RobotOut:
    return RobotOut(
        robot_id=robot.id,
        model_id=robot.model_id,
        scene_version=robot.scene_version or 0,
        created_at=robot.created_at,
        updated_at=robot.updated_at,
    )


@router.put(
    "/{robot_id}",
    status_code=201,
    response_model=RobotOut,
    summary="Create a robot, or re-point it to another model",
    responses={200: {"description": "Robot updated", "model": RobotOut}, 404: {}, 422: {}},
)
def put_robot_route(
    robot_id: str, body: RobotIn, session: SessionDep, response: Response
) -> RobotOut:
    """201 when the robot is new, 200 when it existed."""
    robot, created = put_robot(session=session, robot_id=robot_id, model_id=body.model_id)
    if not created:
        response.status_code = 200
    return _robot_out(robot)


@router.get("/{robot_id}", response_model=RobotOut, summary="A robot", responses=_NOT_FOUND)
def get_robot_route(robot_id: str, session: SessionDep) -> RobotOut:
    """The robot `robot_id`."""
    return _robot_out(get_robot(session=session, robot_id=robot_id))


@dataclass(frozen=True)
class SceneBody:
    """The raw body of a scene upload and its media type."""

    media_type: str
    data: bytes


async def read_scene_body(request: Request, settings: SettingsDep) -> SceneBody:
    """The request body (bounded by max_body_bytes); parsing happens in the worker thread."""
    media = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if media not in JSON_TYPES and media not in YAML_TYPES and not media.endswith("+json"):
        raise HTTPException(
            415, f"unsupported content type {media!r}; send application/json or application/yaml"
        )
    data = await request.body()
    if len(data) > settings.max_body_bytes:
        raise PayloadTooLargeError(
            f"scene body has {len(data)} bytes, more than max_body_bytes={settings.max_body_bytes}"
        )
    return SceneBody(media, data)


SceneBodyDep = Annotated[SceneBody, Depends(read_scene_body)]


def _reject_constant(token: str) -> Any:
    raise SceneError(f"{token} is not allowed in a scene (values must be finite)")


def parse_scene_body(body: SceneBody) -> Scene:
    """A Scene from a JSON (native or MoveIt) or YAML body."""
    try:
        text = body.data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise SceneError("the scene body is not UTF-8 text") from None
    if not text.strip():
        raise SceneError("the scene body is empty")
    if body.media_type in YAML_TYPES:
        return parse_scene_text(text)
    try:
        payload = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise SceneError(f"the scene body is not valid JSON: {exc}") from None
    if not isinstance(payload, dict):
        raise SceneError("a scene must be a JSON object")
    return parse_scene(payload)


@router.put(
    "/{robot_id}/scene",
    response_model=SceneVersionOut,
    summary="Replace the robot's scene (native, MoveIt world, JSON or YAML)",
    openapi_extra=_SCENE_BODY,
    responses={**_NOT_FOUND, 413: {}, 415: {}, 422: {"description": "Malformed scene"}},
)
def put_scene_route(
    robot_id: str, body: SceneBodyDep, ctx: CtxDep, session: SessionDep
) -> SceneVersionOut:
    """A new scene version (or the current one when the content is unchanged)."""
    scene = parse_scene_body(body)
    version, scene_hash = put_scene(
        session=session,
        scenes=ctx.scenes,
        robot_id=robot_id,
        scene=scene,
        max_objects=ctx.settings.max_scene_objects,
    )
    return SceneVersionOut(version=version, hash=scene_hash)


@router.patch(
    "/{robot_id}/scene",
    response_model=SceneVersionOut,
    summary="Upsert or remove scene objects by id, set env values",
    responses={**_NOT_FOUND, 409: {}, 413: {}, 422: {"description": "Malformed patch"}},
)
def patch_scene_route(
    robot_id: str, body: ScenePatchIn, ctx: CtxDep, session: SessionDep
) -> SceneVersionOut:
    """A new scene version with the patch applied."""
    version, scene_hash = patch_scene(
        session=session,
        scenes=ctx.scenes,
        robot_id=robot_id,
        patch=body.model_dump(),
        max_objects=ctx.settings.max_scene_objects,
    )
    return SceneVersionOut(version=version, hash=scene_hash)


@router.get(
    "/{robot_id}/scene",
    response_model=SceneOut,
    summary="The robot's current scene",
    responses=_NOT_FOUND,
)
def get_scene_route(robot_id: str, ctx: CtxDep, session: SessionDep) -> SceneOut:
    """The current scene in native form with its version and hash."""
    info = get_scene(session=session, scenes=ctx.scenes, robot_id=robot_id)
    return SceneOut(version=info.version, hash=info.hash, objects=info.objects, env=info.env)
