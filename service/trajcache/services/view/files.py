"""A model's uploaded files (its meshes), as stored at registration, one at a time."""

from __future__ import annotations

import mimetypes
from dataclasses import dataclass

import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db import models as tables
from trajcache.services.errors import NotFoundError

__all__ = ["StoredFile", "model_file"]

# Mesh formats a URDF refers to, which the standard library's table may not know.
_MEDIA_TYPES = {
    "stl": "model/stl",
    "obj": "model/obj",
    "dae": "model/vnd.collada+xml",
    "ply": "application/octet-stream",
    "glb": "model/gltf-binary",
    "gltf": "model/gltf+json",
}


@dataclass(frozen=True)
class StoredFile:
    """A file of a model's archive: its path there, content, SHA-256 and media type."""

    path: str
    data: bytes
    sha256: str
    media_type: str


def model_file(*, session: Session, model_id: str, path: str) -> StoredFile:
    """The file at `path` in model `model_id`'s archive (only files its URDF refers to are
    stored)."""
    row = session.execute(
        sa.select(tables.ModelFile.data, tables.ModelFile.sha256).where(
            tables.ModelFile.model_id == model_id, tables.ModelFile.path == path
        )
    ).one_or_none()
    if row is None:
        if session.get(tables.RobotModel, model_id) is None:
            raise NotFoundError(f"robot model {model_id!r} not found")
        raise NotFoundError(f"robot model {model_id!r} has no file {path!r}")
    data, sha256 = row
    suffix = path.rsplit(".", 1)[-1].lower() if "." in path else ""
    media = _MEDIA_TYPES.get(suffix) or mimetypes.guess_type(path)[0]
    return StoredFile(path, bytes(data), sha256, media or "application/octet-stream")
