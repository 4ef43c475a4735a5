"""Writing a robot's scene: a new version per change, none for content that is already current.

A robot's first upload is always stored, even when it is the empty scene: version 1 says the
robot gave its world (empty or not), version 0 that it never did (plans then warn, or are
refused under `require_scene`).

Writers of one robot's scene go one after the other under the robot's row lock, so a patch never
loses another's change and identical racing PUTs make one version.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db import models as tables
from trajcache.geometry.scene.payload import apply_patch, scene_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.services.catalog.robots import current_scene
from trajcache.services.catalog.scene_cache import SceneCache
from trajcache.services.catalog.scene_limits import SceneLimits, check_scene
from trajcache.services.errors import ConflictError, NotFoundError

_PATCH_ATTEMPTS = 5


def put_scene(
    *,
    session: Session,
    scenes: SceneCache,
    robot_id: str,
    scene: Scene,
    limits: SceneLimits | None = None,
) -> tuple[int, str]:
    """Replace the robot's scene; return the new (version, hash), or the current ones if equal.

    Identical content keeps its version even when several writers send it at once: each one
    compares with the current scene under the robot's lock (`_write_scene`).
    """
    if limits is not None:
        check_scene(scene, limits)
    return _write_scene(session, scenes, robot_id, lambda _current: scene, what="put")


def patch_scene(
    *,
    session: Session,
    scenes: SceneCache,
    robot_id: str,
    patch: Mapping[str, Any],
    limits: SceneLimits | None = None,
) -> tuple[int, str]:
    """Upsert/remove objects and env values of the current scene; return (version, hash).

    Concurrent patches apply one after the other instead of losing each other's changes.
    """
    return change_scene(
        session=session,
        scenes=scenes,
        robot_id=robot_id,
        change=lambda current: apply_patch(current, patch),
        limits=limits,
        what="patch",
    )


def change_scene(
    *,
    session: Session,
    scenes: SceneCache,
    robot_id: str,
    change: Callable[[Scene], Scene],
    limits: SceneLimits | None = None,
    what: str = "change",
) -> tuple[int, str]:
    """Store `change(current scene)` as the next version (a patch, a MoveIt diff); return
    (version, hash). Changes apply one after the other, each to the scene the last one left."""

    def changed(current: Scene) -> Scene:
        scene = change(current)
        if limits is not None:
            check_scene(scene, limits)
        return scene

    return _write_scene(session, scenes, robot_id, changed, what=what)


def _write_scene(
    session: Session,
    scenes: SceneCache,
    robot_id: str,
    make: Callable[[Scene], Scene],
    *,
    what: str,
) -> tuple[int, str]:
    """Store `make(current scene)` as the robot's next version, unless its content is current.

    The robot row is locked before the current scene is read, so writers go one after the
    other: the second of two identical writes finds the first's version and keeps it.
    """
    for _ in range(_PATCH_ATTEMPTS):
        try:
            _lock_robot(session, robot_id)
            _, current, version = current_scene(session=session, scenes=scenes, robot_id=robot_id)
            scene = make(current)
            if scene.hash == current.hash and version > 0:  # a first upload is stored, even empty
                session.rollback()
                return version, scene.hash
            new_version = _append_version(session, robot_id, scene, expected=version)
        except BaseException:
            session.rollback()
            raise
        if new_version is not None:
            session.commit()
            scenes.put(scene)
            return new_version, scene.hash
        session.rollback()  # another writer got in between: start again from its version
    raise ConflictError(f"the scene of robot {robot_id!r} keeps changing; retry the {what}")


def _lock_robot(session: Session, robot_id: str) -> None:
    """Take the robot's row lock (PostgreSQL) or the write lock (SQLite) until commit."""
    touched = session.execute(
        sa.update(tables.Robot)
        .where(tables.Robot.id == robot_id)
        .values(updated_at=tables.utcnow())
        .execution_options(synchronize_session=False)
    )
    if getattr(touched, "rowcount", 1) == 0:
        raise NotFoundError(f"robot {robot_id!r} not found")


def _append_version(
    session: Session, robot_id: str, scene: Scene, *, expected: int | None
) -> int | None:
    """Bump the robot's scene version (only from `expected` if given) and add the version row.

    The UPDATE locks the robot row first, so concurrent writers get consecutive versions.
    Returns None when the robot is missing or its version is no longer `expected`.
    """
    current = sa.func.coalesce(tables.Robot.scene_version, 0)
    stmt = sa.update(tables.Robot).where(tables.Robot.id == robot_id)
    if expected is not None:
        stmt = stmt.where(current == expected)
    stmt = stmt.values(scene_version=current + 1, updated_at=tables.utcnow())
    version = session.execute(stmt.returning(tables.Robot.scene_version)).scalar_one_or_none()
    if version is None:
        return None
    payload = scene_to_payload(scene)
    session.add(
        tables.SceneVersion(
            robot_id=robot_id,
            version=version,
            hash=scene.hash,
            payload=payload,
            env=dict(scene.env),
        )
    )
    session.flush()
    return int(version)
