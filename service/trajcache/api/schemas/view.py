"""Response bodies of the 3D view: model geometry, stored scenes, and paths as posed links."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from trajcache.api.schemas.common import MODEL_ID, SCENE_HASH, WHEN, examples
from trajcache.api.schemas.rejections import REJECTED_EXAMPLE, RejectedCandidateOut
from trajcache.api.schemas.stats import PlanEventOut

POSE = "x, y, z, qx, qy, qz, qw"
_BOX: dict[str, Any] = {
    "id": "sink_counter",
    "type": "box",
    "size": [1.2, 0.6, 0.85],
    "pose": {"position": [4.9, 0.4, 0.425], "orientation": [0, 0, 0, 1]},
}


class ModelElementOut(BaseModel):
    """A collision element on a link: a primitive by its size, or a mesh by its STL file."""

    model_config = ConfigDict(
        json_schema_extra=examples(
            {
                "link": 3,
                "origin": [0, 0, -0.03, 0, 0, 0, 1],
                "kind": "cylinder",
                "size": [0.045, 0.12],
                "mesh": None,
                "triangles": None,
            }
        )
    )

    link: int = Field(description="Index in `link_names` of the link carrying it.")
    origin: list[float] = Field(description=f"Its pose in the link frame ({POSE}).")
    kind: Literal["box", "sphere", "cylinder", "capsule", "mesh"]
    size: list[float] = Field(
        description="Box: full extents x, y, z; sphere: radius; cylinder and capsule: radius "
        "and length along local z (a capsule's without its caps); mesh: none."
    )
    mesh: str | None = Field(
        description="A mesh's triangles as checked: binary STL at this path (admin key)."
    )
    triangles: int | None = Field(description="How many triangles the mesh has.")


class ModelViewOut(BaseModel):
    """A robot model's links and their collision geometry, as the 3D view draws them."""

    model_config = ConfigDict(
        json_schema_extra=examples(
            {
                "model_id": MODEL_ID,
                "name": "xarm7-mobile",
                "base": "planar",
                "state_names": ["base_x", "base_y", "base_theta", "joint1"],
                "link_names": ["base_link", "link1"],
                "end_effector_link": 1,
                "elements": [
                    {
                        "link": 0,
                        "origin": [0, 0, 0.2, 0, 0, 0, 1],
                        "kind": "box",
                        "size": [0.6, 0.5, 0.4],
                        "mesh": None,
                        "triangles": None,
                    }
                ],
            }
        )
    )

    model_id: str
    name: str
    base: Literal["fixed", "planar"]
    state_names: list[str]
    link_names: list[str]
    end_effector_link: int = Field(description="Index of the link whose origin traces the path.")
    elements: list[ModelElementOut]


class StoredSceneOut(BaseModel):
    """A stored scene in native form: a version of a robot's scene (`robot_id`, `version`), a
    seed job's scene (`seed_job_id`; `created_at` is the job's), or the empty scene (a robot
    that never uploaded one; all three null)."""

    model_config = ConfigDict(
        json_schema_extra=examples(
            {
                "robot_id": "robot-7",
                "version": 2,
                "hash": SCENE_HASH,
                "created_at": WHEN,
                "objects": [_BOX],
                "env": {"stall_2_door": 0.52},
                "allowed_collisions": [],
                "attached_objects": [],
                "seed_job_id": None,
            }
        )
    )

    robot_id: str | None
    version: int | None
    hash: str
    created_at: datetime | None
    objects: list[dict[str, Any]]
    env: dict[str, float]
    allowed_collisions: list[list[str]]
    attached_objects: list[dict[str, Any]]
    seed_job_id: int | None = None


class FramesOut(BaseModel):
    """A path as frames: one per validation sample (evenly thinned beyond 2000), each with
    the world poses of the posed links."""

    count: int = Field(description="Frames.")
    samples: int = Field(description="Validation samples of the whole path.")
    sample: list[int] = Field(description="The validation sample of each frame.")
    key: list[int] = Field(description="The frame of each key state.")
    links: list[int] = Field(
        description="The posed links (indices in the model's `link_names`): those with "
        "collision geometry, the end effector and links the scene attaches objects to."
    )
    states: list[list[float]] = Field(description="The state of each frame.")
    poses: list[list[float]] = Field(
        description=f"Per frame, the world pose of each posed link in `links` order, 7 "
        f"numbers each ({POSE}): computed with the service's kinematics."
    )


class GoalPoseOut(BaseModel):
    """The goal a plan request gave as a link's pose (drawn as a frame marker)."""

    link: str = Field(description="As the request named it (empty: the end-effector link).")
    position: list[float] = Field(
        description="x, y, z (the model's base frame; the world for a planar base)."
    )
    orientation: list[float] = Field(description="Quaternion x, y, z, w.")
    position_tolerance: float
    orientation_tolerance: float


class CartesianLinesOut(BaseModel):
    """The straight lines a Cartesian path follows (drawn as a polyline)."""

    link: str = Field(description="The link whose origin follows the lines.")
    poses: list[list[float]] = Field(
        description=f"The corners ({POSE}): the link's pose at the start, then each waypoint."
    )


class FailureOut(BaseModel):
    """Where a rejected candidate failed: the event's record of it, its frame, and the posed
    links at the failing state (which may lie between two frames)."""

    candidate: int = Field(description="Index in the plan event's `rejections`.")
    frame: int = Field(description="The frame at (or just before) the failing sample.")
    poses: list[float] = Field(description=f"The posed links at the failing state ({POSE}).")
    rejection: RejectedCandidateOut


class PathViewOut(BaseModel):
    """A path to draw: its model, its scene, its frames, and where it failed if it did."""

    model_config = ConfigDict(
        json_schema_extra=examples(
            {
                "model_id": MODEL_ID,
                "state_names": ["base_x", "base_y", "base_theta", "joint1"],
                "trajectory_id": 4207,
                "scene_hash": SCENE_HASH,
                "scene": None,
                "key_states": [[1.3, 1.3, 1.57, 0.0], [1.3, 1.3, 1.57, 0.5]],
                "frames": {
                    "count": 2,
                    "samples": 2,
                    "sample": [0, 1],
                    "key": [0, 1],
                    "links": [0],
                    "states": [[1.3, 1.3, 1.57, 0.0], [1.3, 1.3, 1.57, 0.5]],
                    "poses": [[1.3, 1.3, 0.0, 0, 0, 0.7071, 0.7071]] * 2,
                },
                "failure": {
                    "candidate": 0,
                    "frame": 1,
                    "poses": [1.3, 1.3, 0.0, 0, 0, 0.7071, 0.7071],
                    "rejection": REJECTED_EXAMPLE,
                },
                "event": None,
                "notes": [],
            }
        )
    )

    model_id: str
    state_names: list[str]
    trajectory_id: int | None
    scene_hash: str | None
    scene: StoredSceneOut | None = Field(description="The scene it is shown in, if stored.")
    key_states: list[list[float]]
    frames: FramesOut
    failure: FailureOut | None = Field(description="A rejected candidate's first failure.")
    event: PlanEventOut | None = Field(description="The plan event shown, if one is.")
    notes: list[str] = Field(description="What the view shows otherwise than asked.")
    goal_pose: GoalPoseOut | None = Field(
        default=None, description="A plan event's goal, when the request gave it as a pose."
    )
    cartesian: CartesianLinesOut | None = Field(
        default=None, description="A Cartesian path's lines: its start and waypoints."
    )
