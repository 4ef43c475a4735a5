"""/v1/robots: create or re-point robots; replace, patch and read their scenes."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any

import yaml
from fastapi import APIRouter, BackgroundTasks, Depends, Request, Response
from sqlalchemy.orm import Session

from trajcache.api.bounded import (
    BoundedBodyRoute,
    is_json_media,
    media_type,
    unsupported_media,
)
from trajcache.api.deps import CtxDep, RobotIdPath, SessionDep
from trajcache.api.responses import COMMON, errors
from trajcache.api.schemas.robots import (
    RobotIn,
    RobotOut,
    SceneIn,
    SceneOut,
    ScenePatchIn,
    SceneVersionOut,
)
from trajcache.geometry.errors import SceneError
from trajcache.geometry.scene.frames import root_frames
from trajcache.geometry.scene.moveit_diff import apply_scene_diff, is_scene_diff
from trajcache.geometry.scene.parse import load_scene_text, parse_scene
from trajcache.geometry.scene.scene import Scene
from trajcache.services.catalog.models import get_model
from trajcache.services.catalog.robots import (
    RobotInfo,
    get_robot,
    get_scene,
    put_robot,
    scene_warnings,
)
from trajcache.services.catalog.scene_limits import SceneLimits
from trajcache.services.catalog.scene_writes import change_scene, patch_scene, put_scene
from trajcache.services.context import ServiceContext
from trajcache.services.plan.prepare import prepare_scene

router = APIRouter(
    prefix="/robots", tags=["robots"], responses=COMMON, route_class=BoundedBodyRoute
)

YAML_TYPES = frozenset(
    {"application/yaml", "application/x-yaml", "text/yaml", "text/x-yaml", "text/plain"}
)  # text: YAML or JSON
_YAML_EXAMPLE = """\
world:
  collision_objects:
    - id: table
      primitives: [{type: 1, dimensions: [1.2, 0.8, 0.75]}]
      primitive_poses: [{position: {x: 1.5, y: 0.0, z: 0.375}}]
"""
_SCENE_SCHEMA = SceneIn.model_json_schema()
_SCENE_BODY: dict[str, Any] = {  # a YAML body is read into the same document as a JSON one
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": _SCENE_SCHEMA},
            "application/yaml": {"schema": _SCENE_SCHEMA, "example": yaml.safe_load(_YAML_EXAMPLE)},
        },
    }
}
_UNKNOWN_ROBOT = ("Unknown robot", "robot 'robot-7' not found")
_TOO_LARGE = (
    "Body above max_body_bytes, or more objects than max_scene_objects",
    "request body has 17000000 bytes, more than max_body_bytes=16777216",
)
_NOT_JSON_OR_YAML = (
    "Neither JSON nor YAML",
    "unsupported content type 'image/png'; send application/json or application/yaml",
)


def _robot_out(robot: RobotInfo) -> RobotOut:
    return RobotOut(**dataclasses.asdict(robot))


@router.put(
    "/{robot_id}",
    status_code=201,
    response_model=RobotOut,
    summary="Create a robot, or re-point it to another model",
    response_description="Robot created",
    description="Creates the robot `robot_id` (1-128 letters, digits, `.`, `_`, `:` or `-`, not "
    "only dots) as an instance of a registered model, or re-points an existing robot (201 when "
    "new, 200 when it existed). Robots of one model share one cache. `kind` marks a robot "
    "`real` (the default) or `sim`, so validation statistics can tell real-robot use of a "
    "trajectory apart. "
    "`joint_values` holds joints outside the planning joints otherwise than the model does "
    "(e.g. the gripper open): the robot's plans are checked with those values.",
    responses={
        200: {"description": "Robot updated", "model": RobotOut},
        **errors(
            {
                404: ("Unknown model", "robot model '5158592d' not found"),
                422: (
                    "Malformed robot id or body",
                    "path.robot_id: robot id '..' must be 1-128 letters, digits, '.', '_', "
                    "':' or '-', and not only dots",
                ),
            }
        ),
    },
)
def put_robot_route(
    robot_id: RobotIdPath, body: RobotIn, ctx: CtxDep, session: SessionDep, response: Response
) -> RobotOut:
    """201 when the robot is new, 200 when it existed."""
    robot, created = put_robot(
        session=session,
        robot_id=robot_id,
        model_id=body.model_id,
        kind=body.kind,
        joint_values=body.joint_values,
        models=ctx.models,
    )
    if not created:
        response.status_code = 200
    return _robot_out(RobotInfo.of(robot))


@router.get(
    "/{robot_id}",
    response_model=RobotOut,
    summary="A robot",
    description="The robot's model and its current scene version (0 = no scene uploaded yet).",
    responses=errors({404: _UNKNOWN_ROBOT}),
)
def get_robot_route(robot_id: RobotIdPath, session: SessionDep) -> RobotOut:
    """The robot `robot_id`."""
    return _robot_out(RobotInfo.of(get_robot(session=session, robot_id=robot_id)))


@dataclass(frozen=True)
class SceneBody:
    """The raw body of a scene upload and its media type."""

    media_type: str
    data: bytes


async def read_scene_body(request: Request) -> SceneBody:
    """The request body (bounded by max_body_bytes); parsing happens in the worker thread."""
    media = media_type(request)
    if not is_json_media(media) and media not in YAML_TYPES:
        raise unsupported_media(media, "application/json or application/yaml")
    return SceneBody(media, await request.body())  # bounded while read (BoundedBodyRoute)


SceneBodyDep = Annotated[SceneBody, Depends(read_scene_body)]


def _reject_constant(token: str) -> Any:
    raise SceneError(f"{token} is not allowed in a scene (values must be finite)")


def parse_scene_body(body: SceneBody) -> Scene:
    """A Scene from a JSON (native or MoveIt) or YAML body."""
    return parse_scene(load_scene_body(body))


def load_scene_body(body: SceneBody) -> Mapping[str, Any]:
    """The scene document of a JSON or YAML body, not yet parsed."""
    try:
        text = body.data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise SceneError("the scene body is not UTF-8 text") from None
    if not text.strip():
        raise SceneError("the scene body is empty")
    try:
        if body.media_type in YAML_TYPES:
            return load_scene_text(text)
        payload = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise SceneError(f"the scene body is not valid JSON: {exc}") from None
    except RecursionError:
        raise SceneError("the scene body nests too deeply") from None
    if not isinstance(payload, dict):
        raise SceneError("a scene must be a JSON object")
    return payload


@router.put(
    "/{robot_id}/scene",
    response_model=SceneVersionOut,
    summary="Replace the robot's scene (native, MoveIt world, JSON or YAML)",
    description="Replaces the scene with collision objects in the world frame (box, sphere, "
    "cylinder, capsule, mesh) and named environment values, in native form or as the "
    "`world.collision_objects` of a MoveIt PlanningScene, as JSON or YAML. A PlanningScene's "
    "objects may also be given in the root link's frame of a fixed-base robot, or of a link "
    "fixed to it (as MoveIt resolves it); a planar base's root frame is refused (it moves). "
    "Answers the new version and content hash; unchanged content keeps the current version. "
    "A robot's first upload is stored even when empty: it says the robot's world is empty, and "
    "its plans no longer warn that they were checked for self-collision only.",
    openapi_extra=_SCENE_BODY,
    responses=errors(
        {
            404: _UNKNOWN_ROBOT,
            413: _TOO_LARGE,
            415: _NOT_JSON_OR_YAML,
            422: ("Malformed scene", "object 'a': size must have 3 values, got 0"),
        }
    ),
)
def put_scene_route(
    robot_id: RobotIdPath,
    body: SceneBodyDep,
    ctx: CtxDep,
    session: SessionDep,
    background: BackgroundTasks,
) -> SceneVersionOut:
    """A new scene version (or the current one when the content is unchanged); a MoveIt
    PlanningScene with `is_diff: true` changes the current scene (`moveit_diff.py`). Its
    validator is built once the answer is sent (`services.plan.prepare`)."""
    document = load_scene_body(body)
    background.add_task(prepare_scene, ctx, robot_id)
    if is_scene_diff(document):
        return _put_scene_diff(robot_id, document, ctx, session)
    robot = get_robot(session=session, robot_id=robot_id)
    model = get_model(session=session, registry=ctx.models, model_id=robot.model_id)
    scene = parse_scene(document, root_frames(model))  # objects may be in the root link's frame
    warnings = scene_warnings(model, scene)
    version, scene_hash = put_scene(
        session=session,
        scenes=ctx.scenes,
        robot_id=robot_id,
        scene=scene,
        limits=SceneLimits.of(ctx.settings),
    )
    return SceneVersionOut(version=version, hash=scene_hash, warnings=warnings)


def _put_scene_diff(
    robot_id: str, document: Mapping[str, Any], ctx: ServiceContext, session: Session
) -> SceneVersionOut:
    """Apply a PlanningScene diff to the robot's current scene, under its lock."""
    robot = get_robot(session=session, robot_id=robot_id)
    model = get_model(session=session, registry=ctx.models, model_id=robot.model_id)
    warnings: list[str] = []

    def changed(current: Scene) -> Scene:
        scene = apply_scene_diff(current, document, root_frames(model))
        warnings[:] = scene_warnings(model, scene)
        return scene

    version, scene_hash = change_scene(
        session=session,
        scenes=ctx.scenes,
        robot_id=robot_id,
        change=changed,
        limits=SceneLimits.of(ctx.settings),
    )
    return SceneVersionOut(version=version, hash=scene_hash, warnings=warnings)


@router.patch(
    "/{robot_id}/scene",
    response_model=SceneVersionOut,
    summary="Upsert or remove scene objects by id, set env values",
    description="Adds or replaces objects by id (`upsert`), removes ids (`remove`) and sets "
    "environment values (`env`, null removes one): a door swung open is one small patch. "
    "Answers the new version and hash.",
    responses=errors(
        {
            404: _UNKNOWN_ROBOT,
            409: (
                "The scene kept changing under concurrent patches",
                "the scene of robot 'robot-7' keeps changing; retry the patch",
            ),
            413: (
                "More objects than max_scene_objects",
                "scene has 2001 objects, more than max_scene_objects=2000",
            ),
            422: ("Malformed patch", "object 'door': size must have 3 values, got 2"),
        }
    ),
)
def patch_scene_route(
    robot_id: RobotIdPath,
    body: ScenePatchIn,
    ctx: CtxDep,
    session: SessionDep,
    background: BackgroundTasks,
) -> SceneVersionOut:
    """A new scene version with the patch applied; its validator built once it is answered."""
    background.add_task(prepare_scene, ctx, robot_id)
    version, scene_hash = patch_scene(
        session=session,
        scenes=ctx.scenes,
        robot_id=robot_id,
        patch=body.model_dump(),
        limits=SceneLimits.of(ctx.settings),
    )
    return SceneVersionOut(version=version, hash=scene_hash)


@router.get(
    "/{robot_id}/scene",
    response_model=SceneOut,
    summary="The robot's current scene",
    description="The current scene in native form (MoveIt input is converted), its version "
    "and content hash.",
    responses=errors({404: _UNKNOWN_ROBOT}),
)
def get_scene_route(robot_id: RobotIdPath, ctx: CtxDep, session: SessionDep) -> SceneOut:
    """The current scene in native form with its version and hash."""
    info = get_scene(session=session, scenes=ctx.scenes, robot_id=robot_id)
    return SceneOut(
        version=info.version,
        hash=info.hash,
        objects=info.objects,
        env=info.env,
        allowed_collisions=info.allowed_collisions,
        attached_objects=info.attached_objects,
    )
