"""Stored scene versions: any version of a robot's scene, or a version by its content hash.

A robot's scene versions are immutable and kept (`SceneVersion`), so the scene a trajectory was
stored in, or a plan request was validated in, can be read back by its hash. The empty scene
(a robot that never uploaded one) is known by its hash without being stored.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db import models as tables
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.services.catalog.robots import EMPTY_SCENE, check_robot_id
from trajcache.services.errors import InvalidInputError, NotFoundError

__all__ = ["StoredScene", "scene_by_hash", "scene_version"]

HASH_LENGTH = 64


@dataclass(frozen=True)
class StoredScene:
    """A scene version in native form; `robot_id` and `version` are None for the empty scene."""

    robot_id: str | None
    version: int | None
    hash: str
    created_at: datetime | None
    objects: list[dict[str, Any]]
    env: dict[str, float]
    allowed_collisions: list[list[str]] = field(default_factory=list)
    attached_objects: list[dict[str, Any]] = field(default_factory=list)

    @classmethod
    def of(cls, row: tables.SceneVersion) -> StoredScene:
        """The stored version `row` (its payload is the canonical native form)."""
        payload = row.payload or {}
        return cls(
            robot_id=row.robot_id,
            version=row.version,
            hash=row.hash,
            created_at=row.created_at,
            objects=list(payload.get("objects", [])),
            env=dict(payload.get("env", {})),
            allowed_collisions=list(payload.get("allowed_collisions", [])),
            attached_objects=list(payload.get("attached_objects", [])),
        )


def scene_version(*, session: Session, robot_id: str, version: int) -> StoredScene:
    """Version `version` of robot `robot_id`'s scene."""
    check_robot_id(robot_id)
    row = session.scalar(
        sa.select(tables.SceneVersion).where(
            tables.SceneVersion.robot_id == robot_id, tables.SceneVersion.version == version
        )
    )
    if row is not None:
        return StoredScene.of(row)
    if session.get(tables.Robot, robot_id) is None:
        raise NotFoundError(f"robot {robot_id!r} not found")
    raise NotFoundError(f"robot {robot_id!r} has no scene version {version}")


def scene_by_hash(*, session: Session, scene_hash: str) -> StoredScene:
    """The scene whose content hash is `scene_hash` (its first stored version, any robot's)."""
    text = scene_hash.strip().lower()
    if len(text) != HASH_LENGTH or any(c not in "0123456789abcdef" for c in text):
        raise InvalidInputError(
            f"path.scene_hash: {scene_hash[:80]!r} is not a scene hash (64 hex digits)"
        )
    found = find_scene(session=session, scene_hash=text)
    if found is None:
        raise NotFoundError(f"no stored scene has hash {text!r}")
    return found


def find_scene(*, session: Session, scene_hash: str) -> StoredScene | None:
    """The scene with hash `scene_hash` (the empty scene included), or None."""
    row = session.scalar(
        sa.select(tables.SceneVersion)
        .where(tables.SceneVersion.hash == scene_hash)
        .order_by(tables.SceneVersion.id)
        .limit(1)
    )
    if row is not None:
        return StoredScene.of(row)
    if scene_hash == EMPTY_SCENE.hash:
        payload = scene_to_payload(EMPTY_SCENE)
        return StoredScene(None, None, EMPTY_SCENE.hash, None, payload["objects"], payload["env"])
    return None
