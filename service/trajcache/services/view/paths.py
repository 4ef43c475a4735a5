"""The 3D view of a path: a stored trajectory, or what a plan request validated.

- A stored trajectory is shown in the scene it was stored in (or another stored scene asked
  for by hash), with the model's own held joint values.
- A plan event is shown in the scene the request was validated in. By default, its first
  rejected candidate: the stored path adapted to the request's start and goal again
  (`cache.adapt`, as the plan flow did; the event records both and whether it was reversed),
  opened at the first failing sample with the state that failed and the pairs at fault. Other
  candidates by index; an event without rejections shows its trajectory (as stored: a hit's
  answer replaced its end states with the request's). A candidate deleted since keeps its
  failing state, shown alone. A rejected candidate is posed with the joint values the robot
  held when it was validated (recorded with it); an event's trajectory, with the current ones.
  A request whose goal was a link's pose carries it (`goal_pose`), for a frame marker.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from trajcache.cache.adapt import adapt_trajectory
from trajcache.db import models as tables
from trajcache.geometry.model.poses import link_poses
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.variant import model_in_scene
from trajcache.services.catalog.models import get_model
from trajcache.services.catalog.robots import EMPTY_SCENE, held_values
from trajcache.services.catalog.trajectories import get_trajectory
from trajcache.services.context import ServiceContext
from trajcache.services.errors import NotFoundError
from trajcache.services.view.frames import (
    PathFrames,
    frame_of,
    path_frames,
    posed_links,
    resolution_of,
)
from trajcache.services.view.scenes import StoredScene, find_scene, scene_by_hash

__all__ = ["CartesianLines", "FailureView", "PathView", "plan_event_view", "trajectory_view"]


@dataclass(frozen=True)
class FailureView:
    """Where a rejected candidate failed: its event entry, its frame and the failing poses."""

    candidate: int  # index in the event's rejections
    entry: Mapping[str, Any]  # the event's record (`services.bookkeeping.rejections`)
    frame: int  # the frame at (or just before) the failing sample
    poses: FloatArray  # (K, 7) the posed links at the failing state


@dataclass(frozen=True)
class CartesianLines:
    """The lines a Cartesian path follows: the link, and the poses (x, y, z, qx, qy, qz, qw)
    of its corners: the link's at the start, then each waypoint."""

    link: str
    poses: FloatArray  # (W + 1, 7)


@dataclass(frozen=True)
class PathView:
    """A path to draw: the model, the scene, the frames, and a failure to open at."""

    model_id: str
    state_names: list[str]
    trajectory_id: int | None
    scene_hash: str | None
    scene: StoredScene | None
    key_states: FloatArray
    frames: PathFrames
    failure: FailureView | None = None
    event: tables.PlanEvent | None = None
    notes: list[str] = field(default_factory=list)
    goal_pose: Mapping[str, Any] | None = None  # the plan event's, when its goal was a pose
    cartesian: CartesianLines | None = None  # a Cartesian path's lines (`view.cartesian`)


def trajectory_view(
    *, ctx: ServiceContext, session: Session, trajectory_id: int, scene_hash: str | None = None
) -> PathView:
    """Trajectory `trajectory_id` in the scene it was stored in, or in scene `scene_hash`."""
    row = get_trajectory(session=session, trajectory_id=trajectory_id)
    model = get_model(session=session, registry=ctx.models, model_id=row.model_id)
    notes = []
    scene = None
    if scene_hash is not None:
        scene = scene_by_hash(session=session, scene_hash=scene_hash)
    elif row.scene_hash:
        scene = find_scene(session=session, scene_hash=row.scene_hash)
        if scene is None:  # its robot deleted since, say, or a job from before 0010
            notes.append(f"the scene it was stored in ({row.scene_hash[:12]}…) is not stored")
    else:
        notes.append("it was stored without a scene")
    states = row.states_array()
    return PathView(
        model_id=model.model_id,
        state_names=list(model.state_names),
        trajectory_id=row.id,
        scene_hash=scene.hash if scene is not None else row.scene_hash,
        scene=scene,
        key_states=states,
        frames=_frames(ctx, model, states, scene),
        notes=notes,
    )


def plan_event_view(
    *, ctx: ServiceContext, session: Session, event_id: int, candidate: int | None = None
) -> PathView:
    """Plan event `event_id`: a rejected candidate at its failure, or its trajectory."""
    event = session.get(tables.PlanEvent, event_id)
    if event is None:
        raise NotFoundError(f"plan event {event_id} not found")
    rejections = list(event.rejections or [])
    if candidate is not None and not 0 <= candidate < len(rejections):
        raise NotFoundError(
            f"plan event {event_id} has no rejected candidate {candidate} "
            f"(it has {len(rejections)})"
        )
    if candidate is None and not rejections and event.trajectory_id is None:
        raise NotFoundError(f"plan event {event_id} returned no trajectory and rejected none")
    index = candidate or 0
    entry = rejections[index] if rejections else None  # None: the event's trajectory
    model = _event_model(ctx, session, event, entry)
    scene = find_scene(session=session, scene_hash=event.scene_hash) if event.scene_hash else None
    notes = [] if scene is not None else ["the scene it was validated in is not stored"]
    if entry is None:
        states = _stored_states(session, event.trajectory_id) if event.trajectory_id else None
        if states is None:
            raise NotFoundError(f"trajectory {event.trajectory_id} of plan event {event_id} "
                                "is no longer stored")  # fmt: skip
        if event.source == "cache":
            notes.append("the stored path: the answer replaced its end states with the request's")
        frames = _frames(ctx, model, states, scene)
        return _event_view(event, model, scene, states, frames, None, notes)
    states = _candidate_states(session, model, entry)
    if states is None:
        notes.append(f"trajectory {entry['trajectory_id']} is no longer stored: its failing state")
        states = np.asarray([entry.get("state") or entry["start"]], dtype=float)
    frames = _frames(ctx, model, states, scene)
    failure = _failure(model, frames, index, entry)
    return _event_view(event, model, scene, states, frames, failure, notes, entry["trajectory_id"])


def _event_view(
    event: tables.PlanEvent,
    model: RobotModel,
    scene: StoredScene | None,
    states: FloatArray,
    frames: PathFrames,
    failure: FailureView | None,
    notes: list[str],
    trajectory_id: int | None = None,
) -> PathView:
    return PathView(
        model_id=event.model_id,
        state_names=list(model.state_names),
        trajectory_id=trajectory_id if trajectory_id is not None else event.trajectory_id,
        scene_hash=event.scene_hash,
        scene=scene,
        key_states=states,
        frames=frames,
        failure=failure,
        event=event,
        notes=notes,
        goal_pose=event.goal_pose,
    )


def _event_model(
    ctx: ServiceContext,
    session: Session,
    event: tables.PlanEvent,
    entry: Mapping[str, Any] | None,
) -> RobotModel:
    """The event's model, holding its joints as the rejected candidate `entry` recorded, else
    as the robot does now (if it still exists)."""
    model = get_model(session=session, registry=ctx.models, model_id=event.model_id)
    held: Mapping[str, float] | None
    if entry is not None and isinstance(entry.get("held"), dict):
        held = {str(k): float(v) for k, v in entry["held"].items()} or None
    else:
        robot = session.get(tables.Robot, event.robot_id)
        owned = robot is not None and robot.model_id == model.model_id
        held = held_values(robot.joint_values) if robot is not None and owned else None
    return model_in_scene(model, EMPTY_SCENE, held, cache=ctx.variants)


def _stored_states(session: Session, trajectory_id: int) -> FloatArray | None:
    try:
        return get_trajectory(session=session, trajectory_id=trajectory_id).states_array()
    except NotFoundError:
        return None


def _candidate_states(
    session: Session, model: RobotModel, entry: Mapping[str, Any]
) -> FloatArray | None:
    """The rejected candidate adapted to the request again, as the plan flow validated it."""
    stored = _stored_states(session, int(entry["trajectory_id"]))
    if stored is None or stored.shape[1] != model.dof:
        return None
    return adapt_trajectory(
        stored,
        entry["start"],
        entry["goal"],
        base=model.base,
        reverse=bool(entry.get("reversed")),
    )


def _failure(
    model: RobotModel, frames: PathFrames, index: int, entry: Mapping[str, Any]
) -> FailureView:
    state = entry.get("state")
    if state is None or len(state) != model.dof:  # not located: open at the start
        return FailureView(index, entry, 0, frames.poses[0])
    poses = np.round(link_poses(model, np.asarray([state], dtype=float), frames.links)[0], 6)
    frame = frame_of(frames, int(entry.get("sample") or 0)) if len(frames.states) > 1 else 0
    return FailureView(index, entry, frame, poses)


def _frames(
    ctx: ServiceContext, model: RobotModel, states: FloatArray, scene: StoredScene | None
) -> PathFrames:
    attached = [str(a.get("link", "")) for a in scene.attached_objects] if scene else []
    links = posed_links(model, attached)
    return path_frames(model, states, resolution_of(ctx.settings), links)
