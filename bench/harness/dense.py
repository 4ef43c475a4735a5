"""An independent dense check of returned trajectories: plain FCL, 4× finer steps, no padding.

It shares no code with the service's validator. The robot comes from the URDF text (parsed with
yourdfpy; forward kinematics written out here), the scene from the JSON payload the robot sent to
the service, and every verdict is `fcl.collide` on one pair of primitives at one state.

- Interpolation: straight segments in state space between key states, key states included, with
  at most 0.01 m of base translation, 0.01 rad of base rotation and 0.00875 rad per arm joint
  between samples (the paper's 0.04 m, 0.04 rad and 0.035 rad divided by 4). The base heading
  turns the shorter way round, as a planar base does.
- Pairs: every collision primitive of the robot against every scene object, and every pair of
  robot primitives on links whose pair the model does not allow. A pair goes to FCL unless a
  conservative numpy bound (the primitive's bounding sphere against the object's bounding box,
  or against the other primitive's bounding sphere) shows the two cannot touch. No padding.
- Limits: every sample must lie within the URDF joint limits.
"""

from __future__ import annotations

import io
import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import fcl
import numpy as np
import yourdfpy
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

PAPER_STEPS = (0.04, 0.04, 0.035)  # base position (m), base rotation (rad), joints (rad)
FINER = 4.0
LIMIT_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Primitive:
    """One collision primitive of the robot: its link, FCL object and bounding sphere."""

    link: str
    origin: FloatArray  # 4×4, link frame → primitive frame
    radius: float  # bounding sphere about the primitive's origin
    obj: fcl.CollisionObject = field(repr=False)


@dataclass(frozen=True)
class Obstacle:
    """One scene object: its id, FCL object (posed) and oriented bounding box."""

    id: str
    pose: FloatArray  # 4×4
    half: FloatArray  # (3,) half extents of its box in its own frame
    obj: fcl.CollisionObject = field(repr=False)


@dataclass
class DenseVerdict:
    """What the dense check found along one trajectory."""

    samples: int
    colliding_samples: int = 0
    limit_samples: int = 0
    contacts: set[tuple[str, str]] = field(default_factory=set)  # (link, object or link)

    @property
    def collides(self) -> bool:
        """Whether any sample is in collision."""
        return self.colliding_samples > 0


def _rotation(quat_xyzw: Iterable[float]) -> FloatArray:
    x, y, z, w = (float(v) for v in quat_xyzw)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _axis_rotations(axis: FloatArray, angles: FloatArray) -> FloatArray:
    """(N, 3, 3) rotations by `angles` about the unit `axis` (Rodrigues)."""
    k = axis / np.linalg.norm(axis)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    out: FloatArray = np.eye(3) + s * kx + (1.0 - c) * (kx @ kx)
    return out


def _fcl_geometry(kind: str, size: list[float]) -> tuple[Any, FloatArray]:
    """FCL geometry and the half extents of its box, for a primitive in its own frame."""
    if kind == "box":
        return fcl.Box(*size), np.asarray(size, dtype=float) / 2
    if kind == "sphere":
        return fcl.Sphere(size[0]), np.full(3, size[0])
    if kind == "cylinder":
        return fcl.Cylinder(size[0], size[1]), np.array([size[0], size[0], size[1] / 2])
    if kind == "capsule":
        r, length = size
        return fcl.Capsule(r, length), np.array([r, r, length / 2 + r])
    raise ValueError(f"no dense check for {kind!r} objects")


def _mesh_geometry(vertices: FloatArray, faces: NDArray[np.int64]) -> tuple[Any, FloatArray]:
    bvh = fcl.BVHModel()
    bvh.beginModel(len(vertices), len(faces))
    bvh.addSubModel(vertices, faces)
    bvh.endModel()
    return bvh, np.max(np.abs(vertices), axis=0)


def scene_obstacles(payload: Mapping[str, Any]) -> list[Obstacle]:
    """FCL objects of a scene given as the native JSON payload sent to the service."""
    out = []
    for raw in payload["objects"]:
        pose = np.eye(4)
        pose[:3, :3] = _rotation(raw["pose"]["orientation"])
        pose[:3, 3] = raw["pose"]["position"]
        if raw["type"] == "mesh":
            verts = np.asarray(raw["vertices"], dtype=float)
            geometry, half = _mesh_geometry(verts, np.asarray(raw["faces"], dtype=np.int64))
        else:
            geometry, half = _fcl_geometry(raw["type"], list(raw["size"]))
        obj = fcl.CollisionObject(geometry, fcl.Transform(pose[:3, :3], pose[:3, 3]))
        out.append(Obstacle(raw["id"], pose, half, obj))
    return out


class DenseChecker:
    """Checks trajectories of a planar-base robot (x, y, θ, then its movable joints)."""

    def __init__(self, urdf: str, allowed_pairs: Iterable[tuple[str, str]]) -> None:
        robot = yourdfpy.URDF.load(
            io.StringIO(urdf),
            build_scene_graph=False,
            build_collision_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
        ).robot
        self.joints = _topological(robot.joints, root=_root(robot))
        movable = [j for j in self.joints if j.type in ("revolute", "continuous", "prismatic")]
        self.joint_names = tuple(j.name for j in movable)
        inf = np.inf
        self.lower = np.array(
            [-inf, -inf, -inf]
            + [j.limit.lower if j.type != "continuous" else -inf for j in movable]
        )
        self.upper = np.array(
            [inf, inf, inf] + [j.limit.upper if j.type != "continuous" else inf for j in movable]
        )
        self.root = _root(robot)
        self.primitives = [p for link in robot.links for p in _primitives(link)]
        allowed = {frozenset(p) for p in allowed_pairs}
        self.self_pairs = [
            (a, b)
            for a in range(len(self.primitives))
            for b in range(a + 1, len(self.primitives))
            if self.primitives[a].link != self.primitives[b].link
            and frozenset((self.primitives[a].link, self.primitives[b].link)) not in allowed
        ]
        self.step = np.array(PAPER_STEPS) / FINER
        self._scenes: dict[str, list[Obstacle]] = {}

    def interpolate(self, key_states: FloatArray) -> FloatArray:
        """Dense samples along the straight segments between key states, key states included."""
        key = np.asarray(key_states, dtype=float)
        out = [key[:1]]
        for a, b in itertools.pairwise(key):
            delta = b - a
            delta[2] = (delta[2] + math.pi) % (2 * math.pi) - math.pi
            n = max(
                math.hypot(delta[0], delta[1]) / self.step[0],
                abs(delta[2]) / self.step[1],
                float(np.max(np.abs(delta[3:]), initial=0.0)) / self.step[2],
            )
            count = max(1, math.ceil(n - 1e-12))
            t = np.arange(1, count + 1)[:, None] / count
            out.append(a + t * delta)
        return np.vstack(out)

    def link_poses(self, states: FloatArray) -> dict[str, FloatArray]:
        """(N, 4, 4) world pose of every link at each state."""
        n = len(states)
        base = np.tile(np.eye(4), (n, 1, 1))
        base[:, :3, :3] = _axis_rotations(np.array([0.0, 0.0, 1.0]), states[:, 2])
        base[:, 0, 3], base[:, 1, 3] = states[:, 0], states[:, 1]
        poses = {self.root: base}
        column = {name: 3 + i for i, name in enumerate(self.joint_names)}
        for joint in self.joints:
            pose = poses[joint.parent] @ joint.origin
            if joint.name in column:
                q = states[:, column[joint.name]]
                motion = np.tile(np.eye(4), (n, 1, 1))
                if joint.type == "prismatic":
                    motion[:, :3, 3] = q[:, None] * np.asarray(joint.axis, dtype=float)
                else:
                    motion[:, :3, :3] = _axis_rotations(np.asarray(joint.axis, float), q)
                pose = pose @ motion
            poses[joint.child] = pose
        return poses

    def check(
        self, key_states: FloatArray, scene_key: str, scene_payload: Mapping[str, Any]
    ) -> DenseVerdict:
        """Interpolate `key_states` and check every sample against the scene and itself."""
        obstacles = self._scenes.get(scene_key)
        if obstacles is None:
            obstacles = self._scenes[scene_key] = scene_obstacles(scene_payload)
        states = self.interpolate(key_states)
        verdict = DenseVerdict(samples=len(states))
        outside = np.any(
            (states < self.lower - LIMIT_TOLERANCE) | (states > self.upper + LIMIT_TOLERANCE),
            axis=1,
        )
        verdict.limit_samples = int(outside.sum())
        links = self.link_poses(states)
        # (N, P, 4, 4) world pose of every primitive
        world = np.stack([links[p.link] @ p.origin for p in self.primitives], axis=1)
        colliding = np.zeros(len(states), dtype=bool)
        self._scene_pairs(world, obstacles, colliding, verdict)
        self._self_pairs(world, colliding, verdict)
        verdict.colliding_samples = int(colliding.sum())
        return verdict

    def _scene_pairs(
        self,
        world: FloatArray,
        obstacles: list[Obstacle],
        colliding: NDArray[np.bool_],
        verdict: DenseVerdict,
    ) -> None:
        radius = np.array([p.radius for p in self.primitives])
        centres = world[:, :, :3, 3]  # (N, P, 3)
        for obstacle in obstacles:
            local = (centres - obstacle.pose[:3, 3]) @ obstacle.pose[:3, :3]
            gap = np.linalg.norm(np.maximum(np.abs(local) - obstacle.half, 0.0), axis=-1)
            for s, p in zip(*np.nonzero(gap <= radius), strict=True):
                if self._collide(self.primitives[p].obj, world[s, p], obstacle.obj):
                    colliding[s] = True
                    verdict.contacts.add((self.primitives[p].link, obstacle.id))

    def _self_pairs(
        self, world: FloatArray, colliding: NDArray[np.bool_], verdict: DenseVerdict
    ) -> None:
        centres = world[:, :, :3, 3]
        for a, b in self.self_pairs:
            pa, pb = self.primitives[a], self.primitives[b]
            near = np.linalg.norm(centres[:, a] - centres[:, b], axis=-1) <= pa.radius + pb.radius
            for s in np.flatnonzero(near):
                pb.obj.setTransform(fcl.Transform(world[s, b, :3, :3], world[s, b, :3, 3]))
                if self._collide(pa.obj, world[s, a], pb.obj):
                    colliding[s] = True
                    verdict.contacts.add((pa.link, pb.link))

    @staticmethod
    def _collide(obj: fcl.CollisionObject, pose: FloatArray, other: fcl.CollisionObject) -> bool:
        obj.setTransform(fcl.Transform(pose[:3, :3], pose[:3, 3]))
        result = fcl.CollisionResult()
        return int(fcl.collide(obj, other, fcl.CollisionRequest(), result)) > 0


def _root(robot: Any) -> str:
    children = {j.child for j in robot.joints}
    roots = [link.name for link in robot.links if link.name not in children]
    if len(roots) != 1:
        raise ValueError(f"the URDF must have one root link, found {roots}")
    return str(roots[0])


def _topological(joints: list[Any], root: str) -> list[Any]:
    """Joints ordered parent before child."""
    ordered, reached, pending = [], {root}, list(joints)
    while pending:
        ready = [j for j in pending if j.parent in reached]
        if not ready:
            raise ValueError("the URDF's joints do not form a tree from its root")
        for joint in ready:
            ordered.append(joint)
            reached.add(joint.child)
            pending.remove(joint)
    return ordered


def _primitives(link: Any) -> list[Primitive]:
    out = []
    for collision in link.collisions:
        g = collision.geometry
        if g.box is not None:
            geometry, half = _fcl_geometry("box", list(g.box.size))
        elif g.cylinder is not None:
            geometry, half = _fcl_geometry("cylinder", [g.cylinder.radius, g.cylinder.length])
        elif g.sphere is not None:
            geometry, half = _fcl_geometry("sphere", [g.sphere.radius])
        else:
            raise ValueError(f"link {link.name!r}: no dense check for mesh collision geometry")
        origin = np.eye(4) if collision.origin is None else np.asarray(collision.origin, float)
        radius = float(np.linalg.norm(half)) if g.sphere is None else float(half[0])
        out.append(Primitive(link.name, origin, radius, fcl.CollisionObject(geometry)))
    return out


def reference_checker() -> DenseChecker:
    """The dense checker of the reference robot, with its model's allowed-collision pairs."""
    from trajcache.reference.robot import reference_model, reference_urdf

    model = reference_model()
    allowed = [(model.link_names[a], model.link_names[b]) for a, b in model.allowed_pairs]
    return DenseChecker(reference_urdf(), allowed)
