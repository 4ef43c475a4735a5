"""Stored scene versions: any version of a robot's scene, or a version by its content hash.

A robot's scene versions are immutable and kept (`SceneVersion`), so the scene a trajectory was
stored in, or a plan request was validated in, can be read back by its hash. A seed job keeps
its scenes too (`SeedJobScene`): a hash no robot uploaded is looked up there. The empty scene
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
    """A scene version in native form: a robot's (`robot_id`, `version`), a seed job's
    (`seed_job_id`), or the empty scene (none of them)."""

    robot_id: str | None
    version: int | None
    hash: str
    created_at: datetime | None
    objects: list[dict[str, Any]]
    env: dict[str, float]
    allowed_collisions: list[list[str]] = field(default_factory=list)
    attached_objects: list[dict[str, Any]] = field(default_factory=list)
    seed_job_id: int | None = None

    @classmethod
    def of(cls, row: tables.SceneVersion) -> StoredScene:
        """The stored version `row` (its payload is the canonical native form)."""
        return cls.from_payload(row.payload, row.hash, row.robot_id, row.version, row.created_at)

    @classmethod
    def from_payload(
        cls,
        payload: dict[str, Any] | None,
        scene_hash: str,
        robot_id: str | None = None,
        version: int | None = None,
        created_at: datetime | None = None,
        seed_job_id: int | None = None,
    ) -> StoredScene:
        """A scene from its canonical native form."""
        payload = payload or {}
        return cls(
            robot_id=robot_id,
            version=version,
            hash=scene_hash,
            created_at=created_at,
            objects=list(payload.get("objects", [])),
            env=dict(payload.get("env", {})),
            allowed_collisions=list(payload.get("allowed_collisions", [])),
            attached_objects=list(payload.get("attached_objects", [])),
            seed_job_id=seed_job_id,
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
    """The scene with hash `scene_hash` (the empty scene included): a robot's first version
    with it, else the first seed job's scene with it, else None."""
    row = session.scalar(
        sa.select(tables.SceneVersion)
        .where(tables.SceneVersion.hash == scene_hash)
        .order_by(tables.SceneVersion.id)
        .limit(1)
    )
    if row is not None:
        return StoredScene.of(row)
    if scene_hash == EMPTY_SCENE.hash:
        return StoredScene.from_payload(scene_to_payload(EMPTY_SCENE), EMPTY_SCENE.hash)
    seeded = session.execute(
        sa.select(tables.SeedJobScene, tables.SeedJob.created_at)
        .join(tables.SeedJob, tables.SeedJob.id == tables.SeedJobScene.job_id)
        .where(tables.SeedJobScene.hash == scene_hash)
        .order_by(tables.SeedJobScene.id)
        .limit(1)
    ).first()
    if seeded is None:
        return None
    scene, created_at = seeded
    return StoredScene.from_payload(
        scene.payload, scene.hash, created_at=created_at, seed_job_id=scene.job_id
    )
