"""The 3D view's reads (admin keys): a model's files and render geometry, stored scene
versions, and paths as link poses computed by the service (`services.view`)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Query, Response

from trajcache.api.deps import CtxDep, RobotIdPath, SessionDep
from trajcache.api.responses import COMMON, errors
from trajcache.api.schemas.rejections import RejectedCandidateOut
from trajcache.api.schemas.stats import PlanEventOut
from trajcache.api.schemas.view import (
    CartesianLinesOut,
    FailureOut,
    FramesOut,
    GoalPoseOut,
    ModelElementOut,
    ModelViewOut,
    PathViewOut,
    StoredSceneOut,
)
from trajcache.services.view.cartesian import cartesian_view
from trajcache.services.view.files import model_file
from trajcache.services.view.model import element_stl, model_view
from trajcache.services.view.paths import PathView, plan_event_view, trajectory_view
from trajcache.services.view.scenes import StoredScene, scene_by_hash, scene_version

router = APIRouter(tags=["view"], responses=COMMON)

BINARY = {"schema": {"type": "string", "format": "binary"}}
FILE_BODY = {**BINARY, "example": "(the file's bytes, as uploaded)"}
STL_BODY = {**BINARY, "example": "(binary STL: 80-byte header, triangle count, 50 bytes each)"}
STL = "model/stl"
OCTETS = "application/octet-stream"
IMMUTABLE = "private, max-age=31536000, immutable"  # a model id is the hash of its content
_MODEL_404 = ("Unknown model", "robot model '5158592d' not found")
Id = Annotated[int, Path(ge=1, le=2**63 - 1)]


@router.get(
    "/robot-models/{model_id}/files/{path:path}",
    response_class=Response,
    summary="A file of a model's archive, as uploaded (its meshes)",
    description="The file at `path` in the archive the model was registered with, byte for "
    "byte (the model's answer lists them under `files`). Only files its URDF refers to are "
    "kept. `ETag` is the file's SHA-256.",
    responses={
        200: {"content": {OCTETS: FILE_BODY}, "description": "The file"},
        **errors({404: ("Unknown model or file", "robot model '5158592d' has no file 'a.stl'")}),
    },
)
def model_file_route(model_id: str, path: str, session: SessionDep) -> Response:
    """The stored bytes of one file."""
    found = model_file(session=session, model_id=model_id, path=path)
    name = found.path.rsplit("/", 1)[-1].replace('"', "")
    headers = {
        "ETag": f'"{found.sha256}"',
        "Cache-Control": IMMUTABLE,
        "Content-Disposition": f'attachment; filename="{name}"',
    }
    return Response(found.data, media_type=OCTETS, headers=headers)


@router.get(
    "/robots/{robot_id}/scenes/{version}",
    response_model=StoredSceneOut,
    summary="Any stored version of a robot's scene",
    description="Scene versions are immutable and kept: version `version` in native form, "
    "with its hash and when it was uploaded.",
    responses=errors({404: ("Unknown robot or version", "robot 'robot-7' has no scene version 9")}),
)
def scene_version_route(
    robot_id: RobotIdPath,
    version: Annotated[int, Path(ge=1, le=2**31 - 1)],
    session: SessionDep,
) -> StoredSceneOut:
    """One version of the robot's scene."""
    return _scene_out(scene_version(session=session, robot_id=robot_id, version=version))


@router.get(
    "/scenes/{scene_hash}",
    response_model=StoredSceneOut,
    summary="A stored scene by its content hash",
    description="The first stored version (of any robot) whose content hash is `scene_hash`, "
    "else the first seed job's scene with it (`seed_job_id`): the scene a trajectory was "
    "stored in (`scene_hash` of a trajectory) or a plan request was validated in (`scene_hash` "
    "of a plan event). The empty scene is known by its hash.",
    responses=errors(
        {
            404: ("No stored scene has this hash", "no stored scene has hash '08dd8287…'"),
            422: ("Not a scene hash", "path.scene_hash: 'x' is not a scene hash (64 hex digits)"),
        }
    ),
)
def scene_by_hash_route(scene_hash: str, session: SessionDep) -> StoredSceneOut:
    """The scene with this content hash."""
    return _scene_out(scene_by_hash(session=session, scene_hash=scene_hash))


@router.get(
    "/view/models/{model_id}",
    response_model=ModelViewOut,
    summary="A model's links and collision geometry, for drawing",
    description="Each collision element with its link and its pose there: a primitive by its "
    "size, a mesh by the path of an STL file of the triangles the validator checks (so what "
    "is drawn is what was checked, whatever the uploaded format).",
    responses=errors({404: _MODEL_404}),
)
def model_view_route(model_id: str, ctx: CtxDep, session: SessionDep) -> ModelViewOut:
    """The model's render geometry."""
    view = model_view(session=session, registry=ctx.models, model_id=model_id)
    elements = [
        ModelElementOut(
            link=e.link,
            origin=e.origin,
            kind=e.kind,
            size=e.size,
            mesh=None if e.mesh is None else f"/v1/view/models/{model_id}/meshes/{e.mesh}",
            triangles=e.triangles,
        )
        for e in view.elements
    ]
    return ModelViewOut(
        model_id=view.model_id,
        name=view.name,
        base=view.base,
        state_names=view.state_names,
        link_names=view.link_names,
        end_effector_link=view.end_effector_link,
        elements=elements,
    )


@router.get(
    "/view/models/{model_id}/meshes/{element}",
    response_class=Response,
    summary="A mesh element's triangles as checked, as binary STL",
    description="The triangles of collision element `element` as the validator holds them "
    "(scaled; in the element's frame, which `origin` places on its link).",
    responses={
        200: {"content": {STL: STL_BODY}, "description": "Binary STL"},
        **errors(
            {
                404: (
                    "Unknown model, or not a mesh element",
                    "collision element 0 of robot model '5158592d' is a box, not a mesh",
                )
            }
        ),
    },
)
def model_mesh_route(
    model_id: str,
    element: Annotated[int, Path(ge=0, le=2**31 - 1)],
    ctx: CtxDep,
    session: SessionDep,
) -> Response:
    """One mesh element as STL."""
    data = element_stl(session=session, registry=ctx.models, model_id=model_id, element=element)
    return Response(data, media_type=STL, headers={"Cache-Control": IMMUTABLE})


@router.get(
    "/view/trajectories/{trajectory_id}",
    response_model=PathViewOut,
    summary="A stored trajectory as link poses along its validation samples",
    description="The trajectory in the scene it was stored in (or the stored scene "
    "`scene_hash`): one frame per validation sample at the service's step sizes, each with "
    "the world pose of every link that draws something, computed with the service's "
    "kinematics (a planar base's pose is part of the state).",
    responses=errors(
        {
            404: ("Unknown trajectory or scene", "trajectory 99 not found"),
            422: ("Not a scene hash", "path.scene_hash: 'x' is not a scene hash (64 hex digits)"),
        }
    ),
)
def trajectory_view_route(
    trajectory_id: Id,
    ctx: CtxDep,
    session: SessionDep,
    scene_hash: Annotated[
        str | None, Query(max_length=64, description="Show it in this stored scene.")
    ] = None,
) -> PathViewOut:
    """The trajectory's frames."""
    view = trajectory_view(
        ctx=ctx, session=session, trajectory_id=trajectory_id, scene_hash=scene_hash
    )
    return _path_out(view)


@router.get(
    "/view/plan-events/{event_id}",
    response_model=PathViewOut,
    summary="What a plan request validated, opened where a candidate failed",
    description="In the scene the request was validated in: a rejected candidate (the first, "
    "or `candidate`) adapted to the request as it was validated, with `failure` at its first "
    "failing sample (the state, the link and object or the two links at fault); an event "
    "without rejections shows its trajectory.",
    responses=errors(
        {404: ("Unknown event or candidate", "plan event 7 has no rejected candidate 2 (it has 1)")}
    ),
)
def plan_event_view_route(
    event_id: Id,
    ctx: CtxDep,
    session: SessionDep,
    candidate: Annotated[
        int | None, Query(ge=0, le=1000, description="Index in the event's `rejections`.")
    ] = None,
) -> PathViewOut:
    """The plan event's path."""
    return _path_out(
        plan_event_view(ctx=ctx, session=session, event_id=event_id, candidate=candidate)
    )


@router.get(
    "/view/cartesian-paths/{path_id}",
    response_model=PathViewOut,
    summary="A stored Cartesian path as link poses, with the lines it follows",
    description="The joint path of a Cartesian path the service stored (`path_id` of a "
    "Cartesian path answer), one frame per validation sample, and `cartesian`: the link's pose "
    "at the start and each waypoint, the corners of the straight lines it follows. Stored "
    "without a scene (it is proven in each request's scene), it is shown alone.",
    responses=errors({404: ("Unknown Cartesian path", "Cartesian path 12 not found")}),
)
def cartesian_view_route(path_id: Id, ctx: CtxDep, session: SessionDep) -> PathViewOut:
    """The Cartesian path's frames and lines."""
    return _path_out(cartesian_view(ctx=ctx, session=session, path_id=path_id))


def _scene_out(scene: StoredScene) -> StoredSceneOut:
    return StoredSceneOut(
        robot_id=scene.robot_id,
        version=scene.version,
        hash=scene.hash,
        created_at=scene.created_at,
        objects=scene.objects,
        env=scene.env,
        allowed_collisions=scene.allowed_collisions,
        attached_objects=scene.attached_objects,
        seed_job_id=scene.seed_job_id,
    )


def _path_out(view: PathView) -> PathViewOut:
    frames = view.frames
    count = len(frames.states)
    failure = None
    if view.failure is not None:
        failure = FailureOut(
            candidate=view.failure.candidate,
            frame=view.failure.frame,
            poses=view.failure.poses.ravel().tolist(),
            rejection=RejectedCandidateOut.model_validate(view.failure.entry),
        )
    return PathViewOut(
        model_id=view.model_id,
        state_names=view.state_names,
        trajectory_id=view.trajectory_id,
        scene_hash=view.scene_hash,
        scene=None if view.scene is None else _scene_out(view.scene),
        key_states=view.key_states.tolist(),
        frames=FramesOut(
            count=count,
            samples=frames.samples,
            sample=frames.sample.tolist(),
            key=frames.key.tolist(),
            links=frames.links,
            states=frames.states.tolist(),
            poses=frames.poses.reshape(count, -1).tolist(),
        ),
        failure=failure,
        event=None if view.event is None else PlanEventOut.model_validate(view.event),
        notes=view.notes,
        goal_pose=None if view.goal_pose is None else GoalPoseOut.model_validate(view.goal_pose),
        cartesian=None
        if view.cartesian is None
        else CartesianLinesOut(link=view.cartesian.link, poses=view.cartesian.poses.tolist()),
    )
