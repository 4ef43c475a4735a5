"""The 3D view of a stored Cartesian path: its joint path as frames, and the straight lines it
follows (the link's pose at the start, then each waypoint) for the dashboard to draw.

A Cartesian path is stored without a scene: it is proven in each request's scene when it
serves (`services.cartesian.store`), so it is shown alone, with the model's own held joint
values.
"""

from __future__ import annotations

import numpy as np
from sqlalchemy.orm import Session

from trajcache.db.cartesian import CartesianPathRow
from trajcache.geometry.model.poses import link_poses
from trajcache.services.catalog.models import get_model
from trajcache.services.context import ServiceContext
from trajcache.services.errors import NotFoundError
from trajcache.services.view.frames import path_frames, posed_links, resolution_of
from trajcache.services.view.paths import CartesianLines, PathView

__all__ = ["cartesian_view"]

NO_SCENE = "a Cartesian path is stored without a scene: it is proven in each request's scene"


def cartesian_view(*, ctx: ServiceContext, session: Session, path_id: int) -> PathView:
    """Stored Cartesian path `path_id`: its frames and its lines."""
    row = session.get(CartesianPathRow, path_id)
    if row is None:
        raise NotFoundError(f"Cartesian path {path_id} not found")
    model = get_model(session=session, registry=ctx.models, model_id=row.model_id)
    states = np.asarray(row.states, dtype=float)
    link = model.link_names.index(row.link)
    start = link_poses(model, states[:1], [link])[0, 0]
    corners = np.vstack([start, np.asarray(row.waypoints, dtype=float)])
    frames = path_frames(model, states, resolution_of(ctx.settings), posed_links(model))
    return PathView(
        model_id=model.model_id,
        state_names=list(model.state_names),
        trajectory_id=None,
        scene_hash=None,
        scene=None,
        key_states=states,
        frames=frames,
        notes=[NO_SCENE],
        cartesian=CartesianLines(row.link, np.round(corners, 6)),
    )
