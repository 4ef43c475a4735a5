"""Robots and their versioned scenes; parsed scenes are cached by hash for the plan flow."""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from datetime import datetime
from typing import TYPE_CHECKING, Any

import sqlalchemy as sa
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from trajcache.db import models as tables
from trajcache.db.session import Reads, connection_of
from trajcache.db.sources import read_scene_payload
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene, make_scene
from trajcache.geometry.scene.variant import model_in_scene
from trajcache.services.catalog.models import ModelRegistry, get_model
from trajcache.services.catalog.scene_cache import SceneCache
from trajcache.services.errors import (
    InvalidInputError,
    NotFoundError,
)

if TYPE_CHECKING:
    from trajcache.services.catalog.index_store import AnySelect

# Letters, digits and `._:-`, not only dots: "." and ".." are path segments no URL can carry.
ROBOT_ID_PATTERN = r"^\.*[A-Za-z0-9_:-][A-Za-z0-9._:-]*$"
ROBOT_ID_MAX_LENGTH = 128
_ROBOT_ID = re.compile(ROBOT_ID_PATTERN)
EMPTY_SCENE = make_scene([], {})


@dataclass(frozen=True)
class RobotInfo:
    """A robot as returned by the API."""

    robot_id: str
    model_id: str
    kind: str
    scene_version: int  # 0: no scene uploaded yet
    created_at: datetime
    updated_at: datetime
    joint_values: dict[str, float]

    @classmethod
    def of(cls, robot: tables.Robot) -> RobotInfo:
        """The API view of a robot row."""
        held = held_values(robot.joint_values) or {}
        version = robot.scene_version or 0
        return cls(
            robot.id, robot.model_id, robot.kind, version, robot.created_at, robot.updated_at, held
        )


@dataclass(frozen=True)
class SceneInfo:
    """A robot's current scene as returned by the API."""

    version: int
    hash: str
    objects: list[dict[str, Any]]
    env: dict[str, float]
    allowed_collisions: list[list[str]]
    attached_objects: list[dict[str, Any]]


def check_robot_id(robot_id: str) -> str:
    """`robot_id` if it is 1–128 characters of letters, digits and `._:-`, not only dots."""
    if len(robot_id) > ROBOT_ID_MAX_LENGTH or not _ROBOT_ID.fullmatch(robot_id):
        raise InvalidInputError(
            f"robot id {robot_id[:140]!r} must be 1-{ROBOT_ID_MAX_LENGTH} letters, digits, "
            "'.', '_', ':' or '-', and not only dots"
        )
    return robot_id


ROBOT_KINDS = ("real", "sim")


def put_robot(
    *,
    session: Session,
    robot_id: str,
    model_id: str,
    kind: str | None = None,
    joint_values: Mapping[str, float] | None = None,
    models: ModelRegistry | None = None,
) -> tuple[tables.Robot, bool]:
    """Create robot `robot_id` of model `model_id`, or re-point it; return it and `created`.

    `kind` (`real` or `sim`) is set when given; a new robot without it is `real`. `joint_values`
    (given: set, `{}` clears them) hold joints outside the planning joints otherwise than the
    model does; they are checked against the model (StateError names a value it cannot hold),
    as are values kept from before when the robot moves to another model.
    """
    check_robot_id(robot_id)
    if kind is not None and kind not in ROBOT_KINDS:
        raise InvalidInputError(f"robot kind {kind!r} must be one of {', '.join(ROBOT_KINDS)}")
    if (
        session.scalar(sa.select(tables.RobotModel.id).where(tables.RobotModel.id == model_id))
        is None
    ):
        raise NotFoundError(f"robot model {model_id!r} not found")
    robot = session.get(tables.Robot, robot_id)
    held_text = robot.joint_values if robot is not None else None
    if joint_values is not None:
        held_text = json.dumps(dict(sorted(joint_values.items()))) if joint_values else None
    if held_text is not None:
        model = get_model(session=session, registry=models or ModelRegistry(), model_id=model_id)
        model_in_scene(model, EMPTY_SCENE, held_values(held_text))  # raises if it cannot hold
    if robot is None:
        robot = tables.Robot(
            id=robot_id,
            model_id=model_id,
            scene_version=None,
            kind=kind or "real",
            joint_values=held_text,
        )
        session.add(robot)
        try:
            session.commit()
            return robot, True
        except IntegrityError:  # created concurrently: fall through to re-pointing it
            session.rollback()
            robot = session.get(tables.Robot, robot_id)
            if robot is None:
                raise
    if (
        robot.model_id != model_id
        or (kind is not None and robot.kind != kind)
        or robot.joint_values != held_text
    ):
        robot.model_id = model_id
        robot.kind = kind or robot.kind
        robot.joint_values = held_text
        robot.updated_at = tables.utcnow()
        session.commit()
    return robot, False


def get_robot(*, session: Session, robot_id: str) -> tables.Robot:
    """The robot `robot_id`."""
    robot = session.get(tables.Robot, robot_id)
    if robot is None:
        raise NotFoundError(f"robot {robot_id!r} not found")
    return robot


@dataclass(frozen=True)
class RobotScene:
    """What a plan needs to know about a robot: its model and its current scene."""

    robot_id: str
    model_id: str
    scene: Scene
    version: int  # 0: no scene uploaded yet (the empty scene)
    kind: str = "real"  # "real" or "sim"
    joint_values: Mapping[str, float] | None = None  # the robot's own held joint values


def robot_scene(
    *,
    session: Reads,
    scenes: SceneCache,
    robot_id: str,
    read_fn: Callable[[AnySelect, Mapping[str, Any]], Sequence[Any] | None] | None = None,
) -> RobotScene:
    """The robot's model id and current scene; one query when the scene is cached.

    `read_fn` runs that query (a select of at most one row, and its parameters) and returns its
    row: the plan flow reads it together with the replica sync (`IndexStore.read_with_sync`).
    """
    params = {"robot_id": robot_id}
    row: Sequence[Any] | None
    if read_fn is None:
        row = connection_of(session).execute(ROBOT_SCENE, params).one_or_none()
    else:
        row = read_fn(ROBOT_SCENE, params)
    if row is None:
        raise NotFoundError(f"robot {robot_id!r} not found")
    model_id, version, scene_hash, kind, held = row
    scene, version = _resolve_scene(session, scenes, robot_id, version or 0, scene_hash)
    return RobotScene(robot_id, model_id, scene, version, kind, held_values(held))


def current_scene(
    *, session: Session, scenes: SceneCache, robot_id: str
) -> tuple[tables.Robot, Scene, int]:
    """The robot, its current scene and version (0: empty) in one query when the scene is cached."""
    row = session.execute(
        sa.select(tables.Robot, tables.SceneVersion.hash)
        .outerjoin(tables.SceneVersion, _current_version())
        .where(tables.Robot.id == robot_id)
    ).one_or_none()
    if row is None:
        raise NotFoundError(f"robot {robot_id!r} not found")
    robot, scene_hash = row
    scene, version = _resolve_scene(session, scenes, robot_id, robot.scene_version or 0, scene_hash)
    return robot, scene, version


def _current_version() -> sa.ColumnElement[bool]:
    return sa.and_(
        tables.SceneVersion.robot_id == tables.Robot.id,
        tables.SceneVersion.version == tables.Robot.scene_version,
    )


ROBOT_SCENE: AnySelect = (  # built once: the plan flow runs it on every request
    sa.select(
        tables.Robot.model_id,
        tables.Robot.scene_version,
        tables.SceneVersion.hash,
        tables.Robot.kind,
        tables.Robot.joint_values,
    )
    .outerjoin(tables.SceneVersion, _current_version())
    .where(tables.Robot.id == sa.bindparam("robot_id", type_=sa.String))
)


def held_values(text: str | None) -> dict[str, float] | None:
    """A robot's held joint values from their stored JSON text (None: the model's)."""
    if not text:
        return None
    values = json.loads(text)
    return {str(k): float(v) for k, v in values.items()}


def _resolve_scene(
    session: Reads, scenes: SceneCache, robot_id: str, version: int, scene_hash: str | None
) -> tuple[Scene, int]:
    """The parsed scene of a robot's version (from the cache, else its stored payload)."""
    if version == 0 or scene_hash is None:
        return EMPTY_SCENE, 0
    scene = scenes.get(scene_hash)
    if scene is None:
        payload = connection_of(session).scalar(
            sa.select(tables.SceneVersion.payload).where(
                tables.SceneVersion.robot_id == robot_id, tables.SceneVersion.version == version
            )
        )
        scene = parse_scene(payload or {})
        if scene.hash != scene_hash:  # the stored hash names this version everywhere
            scene = replace(scene, hash=scene_hash)
        scene = scenes.put(scene)
    return scene, version


def stored_scene_payload(*, session: Session, scene_hash: str) -> dict[str, Any]:
    """The stored payload of the scene with hash `scene_hash` (whichever robot uploaded it)."""
    payload = read_scene_payload(session, scene_hash)
    if payload is None:
        raise NotFoundError(f"scene {scene_hash!r} not found")
    return payload


def get_scene(*, session: Session, scenes: SceneCache, robot_id: str) -> SceneInfo:
    """The robot's current scene in native form, with its version and hash."""
    _, scene, version = current_scene(session=session, scenes=scenes, robot_id=robot_id)
    payload = scene_to_payload(scene)
    return SceneInfo(
        version,
        scene.hash,
        payload["objects"],
        payload["env"],
        payload.get("allowed_collisions", []),
        payload.get("attached_objects", []),
    )


def scene_warnings(model: RobotModel, scene: Scene) -> list[str]:
    """The scene's own warnings, and its names that are neither a link of `model` nor one of
    its objects; SceneError when an attached object cannot be attached to the model."""
    model_in_scene(model, scene)  # an unknown link to attach to, or a name clash, is an error
    known = set(model.link_names) | {o.id.partition("#")[0] for o in scene.objects}
    known |= {a.object.id.partition("#")[0] for a in scene.attached}
    out = list(scene.warnings)
    unknown = sorted({n for pair in scene.allowed for n in pair if n not in known})
    if unknown:
        out.append(f"allowed collisions name unknown links or objects {unknown}; not applied")
    touch = sorted({t for a in scene.attached for t in a.touch_links if t not in known})
    if touch:
        out.append(f"touch_links name unknown links {touch}; not applied")
    return out
