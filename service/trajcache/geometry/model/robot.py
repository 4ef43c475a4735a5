"""The robot model: planning joints, limits, collision geometry and the kinematic tree."""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind

BASE_STATE_NAMES = ("base_x", "base_y", "base_theta")


class BaseType(str, Enum):
    """How the robot's root link is placed in the world."""

    FIXED = "fixed"
    PLANAR = "planar"

    @property
    def arm_offset(self) -> int:
        """Index of the first arm joint in a state vector: after a planar base's x, y, θ."""
        return 3 if self is BaseType.PLANAR else 0


@dataclass(frozen=True, eq=False)
class CollisionElement:
    """One collision shape rigidly attached to a link, posed in the link frame."""

    link: int
    shape: Shape
    origin: FloatArray  # 4×4, link frame → shape frame

    @classmethod
    def placed(cls, link: int, shape: Shape, origin: FloatArray) -> CollisionElement:
        """The element of `shape` at `origin` on `link`, a mesh moved to be centred on its
        box and the origin moved the other way: the same geometry in the link frame, but its
        bounding ball, which the cheapest bounds and every motion bound use, is centred on the
        mesh rather than on wherever its file put the origin (a third smaller on the
        `example-robot-data` arms)."""
        if shape.kind is not ShapeKind.MESH or shape.vertices is None:
            return cls(link, shape, origin)
        centre = (shape.vertices.min(axis=0) + shape.vertices.max(axis=0)) / 2.0
        moved = Shape(ShapeKind.MESH, vertices=shape.vertices - centre, faces=shape.faces)
        shift = np.eye(4)
        shift[:3, 3] = centre
        return cls(link, moved, np.asarray(origin, dtype=float) @ shift)


@dataclass(frozen=True, eq=False)
class KinematicJoint:
    """One URDF joint in topological order (parent before child).

    `index` is the joint's position in the state vector, or -1 when it is not a planning joint
    (fixed joints, and movable joints held at `default`). A joint that mimics a planning joint
    has its leader's index, and takes `scale` · value + `offset`.
    """

    name: str
    kind: str  # "fixed" | "revolute" | "continuous" | "prismatic"
    parent: int  # link index
    child: int  # link index
    origin: FloatArray  # 4×4, parent link frame → joint frame at zero position
    axis: FloatArray  # unit 3-vector in the joint frame
    index: int = -1
    default: float = 0.0
    bounds: tuple[float, float] | None = None  # limits of a movable joint (None: unbounded)
    mimic: tuple[str, float, float] | None = None  # (leader joint, multiplier, offset)

    @property
    def scale(self) -> float:
        """Multiplier of the state value `index` in this joint's value (a mimic joint's)."""
        return self.mimic[1] if self.mimic is not None and self.index >= 0 else 1.0

    @property
    def offset(self) -> float:
        """Offset added to the scaled state value (a mimic joint's)."""
        return self.mimic[2] if self.mimic is not None and self.index >= 0 else 0.0


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A robot ready for kinematics and collision checking.

    States are ordered as `state_names`: for a planar base (x, y, θ) first, then the planning
    joints in `joint_names` order. Link 0 is the root link; the planar base moves it in the world.
    """

    model_id: str
    name: str
    base: BaseType
    joint_names: tuple[str, ...]
    link_names: tuple[str, ...]
    joints: tuple[KinematicJoint, ...]
    elements: tuple[CollisionElement, ...]
    lower: FloatArray  # per state value; base x, y are -inf/+inf, θ is -π/π (wrapped)
    upper: FloatArray
    velocity_limits: FloatArray  # per state value
    # Link pairs (i < j) whose self-collisions are not checked, and why ("adjacent", "rigid",
    # "srdf", "scene"); `allowed_pairs` are its keys.
    pair_reasons: Mapping[tuple[int, int], str] = field(default_factory=dict)
    # Values of the movable joints outside the planning joints (held, mimic joints included).
    held_values: Mapping[str, float] = field(default_factory=dict)
    # SRDF group states that give every planning joint a value, in joint_names order.
    named_states: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()  # what of the SRDF was not applied
    # Configuration given at registration: acceleration and jerk limits per planning joint
    # (joint_names order; NaN or None: the service default) and the end-effector link (None: the
    # tip of the longest kinematic chain).
    acceleration_limits: FloatArray | None = None
    jerk_limits: FloatArray | None = None
    end_effector_link: str | None = None

    @functools.cached_property
    def allowed_pairs(self) -> frozenset[tuple[int, int]]:
        """Link pairs (i < j) whose self-collisions are not checked."""
        return frozenset(self.pair_reasons)

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the state values in order."""
        prefix = BASE_STATE_NAMES if self.base is BaseType.PLANAR else ()
        return prefix + self.joint_names

    @property
    def dof(self) -> int:
        """Length of a state vector."""
        return len(self.joint_names) + (3 if self.base is BaseType.PLANAR else 0)

    @property
    def arm_offset(self) -> int:
        """Index of the first arm joint in a state vector."""
        return self.base.arm_offset

    def geometric_links(self) -> np.ndarray:
        """Indices of links that carry at least one collision element."""
        return np.unique(np.array([e.link for e in self.elements], dtype=np.int64))
