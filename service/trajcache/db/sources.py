"""What a planner needs of a stored model or scene, read straight from the tables.

Shared by the service's catalog (`services.catalog`) and the Celery workers (`jobs.sources`),
which hold no service context: both rebuild a model from the same rows. None means the row is
not there; each caller says so in its own terms.
"""

from __future__ import annotations

from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db import models as tables
from trajcache.planning.problem import ModelSource


def stored_files(session: Session, model_id: str) -> dict[str, bytes]:
    """The files (meshes) registered with model `model_id`, by their path."""
    rows = session.execute(
        sa.select(tables.ModelFile.path, tables.ModelFile.data).where(
            tables.ModelFile.model_id == model_id
        )
    )
    return {path: data for path, data in rows}


def read_model_source(session: Session, model_id: str) -> ModelSource | None:
    """What a planner worker needs to rebuild model `model_id` (picklable); None if unknown."""
    row = session.get(tables.RobotModel, model_id)
    if row is None:
        return None
    return ModelSource(
        model_id=row.id,
        urdf=row.urdf,
        base=row.base,
        joint_names=tuple(row.joint_names),
        files=stored_files(session, model_id),
        srdf=(row.config or {}).get("srdf"),
        joint_values=(row.config or {}).get("joint_values"),
    )


def read_scene_payload(session: Session, scene_hash: str) -> dict[str, Any] | None:
    """The stored payload of the scene with hash `scene_hash` (whichever robot uploaded it);
    None if no robot did."""
    query = sa.select(tables.SceneVersion.payload).where(tables.SceneVersion.hash == scene_hash)
    payload = session.scalar(query.limit(1))
    return None if payload is None else dict(payload)
