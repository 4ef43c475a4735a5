"""An independent dense check on real robot descriptions: Pinocchio and coal, meshes as shipped.

It shares no code with the service's validator: the robot is read by `pin.buildModelFromUrdf`
and `pin.buildGeomFromUrdf` (collision meshes as coal BVH models, not convex hulls, an OBJ file's
triangles read as written rather than through assimp: `coal_geometry.obj_triangles`; URDF
primitives as coal primitives), the scene from the native payload sent to the service, and every
verdict is `pin.computeCollisions` over explicit pairs at one state.

- States: the service's order, base x, y, θ first for a planar base (the root link then moves on
  a `pin.JointModelPlanar`), then the planning joints. Joints outside the state are held at the
  given value, else at 0 clipped into their limits; a mimic joint follows its leader
  (multiplier · leader + offset), whether the leader is planned or held.
- Self pairs: every two geometries on different bodies, minus the SRDF's disable_collisions
  (when an SRDF is applied), minus adjacent bodies. A body is the set of links that move as one
  while planning: links joined by fixed joints, and by held joints too (a held joint is as fixed
  as a fixed joint: the pair's relative pose never changes, so its verdict could never change
  either); a moving joint is a planning joint, a mimic of one, or the planar root. Two bodies are
  adjacent when one is the other's parent, where a body without collision geometry is skipped
  through.
- Scene pairs: every robot geometry against every scene object (box, sphere, cylinder, capsule).
  The depth reported is coal's deepest contact penetration over the scene pairs in contact.
- Interpolation: straight segments between key states, key states included, with at most
  0.00875 rad (revolute) or 0.01 m (prismatic) per planning joint, 0.01 m of base translation
  and 0.01 rad of base rotation between samples (the paper's steps divided by 4); the base
  heading turns the shorter way round. No padding anywhere.
- Limits: a sample outside a planning joint's URDF limits (by more than 1e-9) is a violation.
"""

from __future__ import annotations

import itertools
from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from coal_geometry import (
    FloatArray,
    obj_meshes_as_written,
    quaternion_placement,
    scene_geometry,
)
from robot_description import RobotDescription, urdf_mimics

JOINT_STEP, PRISMATIC_STEP, BASE_STEP, HEADING_STEP = 0.00875, 0.01, 0.01, 0.01
LIMIT_TOLERANCE = 1e-9


@dataclass
class PathVerdict:
    """The dense check of one path."""

    samples: int = 0
    scene_samples: int = 0  # samples in contact with the scene
    self_samples: int = 0  # samples in self-collision
    limit_samples: int = 0  # samples outside the joint limits
    max_depth: float = 0.0  # deepest scene penetration seen (m)
    scene_pairs: Counter[str] = field(default_factory=Counter)  # "link–object" → samples
    self_pairs: Counter[str] = field(default_factory=Counter)  # "link–link" → samples

    @property
    def collides(self) -> bool:
        """Whether the path touches the scene."""
        return self.scene_samples > 0

    @property
    def self_collides(self) -> bool:
        """Whether the robot touches itself somewhere on the path."""
        return self.self_samples > 0


class MeshChecker:
    """Collision and limit checks of one robot in one scene at a time."""

    def __init__(self, robot: RobotDescription) -> None:
        self.robot = robot
        urdf_path = str(robot.urdf_path)
        self.planar = robot.base == "planar"
        root = pin.JointModelPlanar() if self.planar else None
        model = (
            pin.buildModelFromUrdf(urdf_path, root) if root else pin.buildModelFromUrdf(urdf_path)
        )
        geoms = pin.buildGeomFromUrdf(
            model, urdf_path, pin.COLLISION, package_dirs=[str(robot.package_dir)]
        )
        obj_meshes_as_written(geoms)
        self.model, self.data = model, model.createData()
        self.robot_geoms = geoms
        self.joint_ids = [model.getJointId(name) for name in robot.joint_names]
        missing = [
            n for n, j in zip(robot.joint_names, self.joint_ids, strict=True) if j >= model.njoints
        ]
        if missing:
            raise ValueError(f"joints {missing} are not movable joints of the URDF")
        self.lower, self.upper, self.steps = self._bounds()
        self.mimics = urdf_mimics(robot.urdf_path.read_text(encoding="utf-8"))
        self.self_pairs = self._self_pairs(geoms, robot.srdf_path)
        self.held_q = self._held_configuration()
        last = self.joint_ids[-1]
        tips = [
            f
            for f, frame in enumerate(model.frames)
            if frame.parentJoint == last and frame.type == pin.FrameType.BODY
        ]
        self.tip_frame = max(
            tips, key=lambda f: float(np.linalg.norm(model.frames[f].placement.translation))
        )
        self.set_scene([])

    # --- the robot ----------------------------------------------------------------------------

    def _self_pairs(self, geoms: pin.GeometryModel, srdf: Path | None) -> list[tuple[int, int]]:
        """The checked self pairs; sets `geom_body`, the body (a moving joint) of each geometry."""
        parent = self.model.parents
        moving = {0, *self.joint_ids, *([1] if self.planar else [])}
        moving |= {self.model.getJointId(f) for f, (lead, _, _) in self.mimics.items()
                   if lead in self.robot.joint_names and self.model.existJointName(f)}  # fmt: skip

        def body(joint: int) -> int:  # held joints are as fixed as fixed joints
            while joint not in moving:
                joint = parent[joint]
            return joint

        self.geom_body = [body(g.parentJoint) for g in geoms.geometryObjects]
        with_geometry = set(self.geom_body)

        def body_parent(joint: int) -> int:  # skipping bodies without collision geometry
            joint = body(parent[joint]) if joint else 0
            while joint > 0 and joint not in with_geometry:
                joint = body(parent[joint])
            return joint

        trial = pin.GeometryModel(geoms)
        trial.addAllCollisionPairs()
        if srdf is not None:
            pin.removeCollisionPairs(self.model, trial, str(srdf))
        pairs = []
        for pair in trial.collisionPairs:
            a, b = self.geom_body[pair.first], self.geom_body[pair.second]
            if a != b and a != body_parent(b) and b != body_parent(a):
                pairs.append((pair.first, pair.second))
        return pairs

    def _bounds(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        lower, upper, steps = [], [], []
        self.prismatic: list[bool] = []  # per planning joint
        if self.planar:
            lower += [-np.inf] * 3
            upper += [np.inf] * 3
            steps += [BASE_STEP, BASE_STEP, HEADING_STEP]
        for jid in self.joint_ids:
            joint = self.model.joints[jid]
            if joint.nq == 1:
                lower.append(float(self.model.lowerPositionLimit[joint.idx_q]))
                upper.append(float(self.model.upperPositionLimit[joint.idx_q]))
            else:  # continuous: (cos, sin)
                lower.append(-np.inf)
                upper.append(np.inf)
            prismatic = joint.shortname().startswith("JointModelP")
            self.prismatic.append(prismatic)
            steps.append(PRISMATIC_STEP if prismatic else JOINT_STEP)
        return np.array(lower), np.array(upper), np.array(steps)

    def _set(self, q: FloatArray, jid: int, value: float) -> None:
        joint = self.model.joints[jid]
        if joint.nq == 1:
            q[joint.idx_q] = value
        elif joint.nq == 2:  # continuous
            q[joint.idx_q : joint.idx_q + 2] = (np.cos(value), np.sin(value))

    def _held_configuration(self) -> FloatArray:
        q = pin.neutral(self.model)
        model = self.model
        for jid in range(1, model.njoints):
            if jid in self.joint_ids or (self.planar and jid == 1):
                continue
            name, joint = model.names[jid], model.joints[jid]
            value = self.robot.held.get(name, 0.0)
            if joint.nq == 1:
                lo, hi = (
                    model.lowerPositionLimit[joint.idx_q],
                    model.upperPositionLimit[joint.idx_q],
                )
                value = float(np.clip(value, lo, hi))
            self._set(q, jid, value)
        return q

    def configuration(self, state: ArrayLike) -> FloatArray:
        """The Pinocchio configuration of a state (held joints and mimic joints filled in)."""
        values_in = np.asarray(state, dtype=float)
        q = self.held_q.copy()
        arm = values_in[3:] if self.planar else values_in
        values = dict(zip(self.robot.joint_names, arm, strict=True))
        if self.planar:
            x, y, theta = values_in[:3]
            q[:4] = (x, y, np.cos(theta), np.sin(theta))
        for jid, value in zip(self.joint_ids, values.values(), strict=True):
            self._set(q, jid, value)
        for follower, (leader, multiplier, offset) in self.mimics.items():
            if not self.model.existJointName(follower):
                continue
            if leader in values:
                lead = values[leader]
            else:
                jl = self.model.joints[self.model.getJointId(leader)]
                lead = float(q[jl.idx_q])
            self._set(q, self.model.getJointId(follower), multiplier * lead + offset)
        return q

    def tip_position(self, state: ArrayLike) -> FloatArray:
        """World position of the end effector (the farthest frame of the last planning joint)."""
        q = self.configuration(state)
        pin.framesForwardKinematics(self.model, self.data, q)
        return np.array(self.data.oMf[self.tip_frame].translation)

    def joint_position(self, state: ArrayLike, name: str) -> FloatArray:
        """World position of a joint's frame."""
        pin.forwardKinematics(self.model, self.data, self.configuration(state))
        return np.array(self.data.oMi[self.model.getJointId(name)].translation)

    # --- the scene ----------------------------------------------------------------------------

    def set_scene(self, objects: Iterable[Mapping[str, Any]]) -> None:
        """Check against these scene objects (native payload) from now on."""
        geoms = pin.GeometryModel()
        for obj in self.robot_geoms.geometryObjects:
            geoms.addGeometryObject(obj)
        self.object_ids: list[str] = []
        for obj in objects:
            placement = quaternion_placement(obj.get("pose"))
            geoms.addGeometryObject(
                pin.GeometryObject(f"scene:{obj['id']}", 0, 0, placement, scene_geometry(obj))
            )
            self.object_ids.append(str(obj["id"]))
        n = len(self.robot_geoms.geometryObjects)
        for a, b in self.self_pairs:
            geoms.addCollisionPair(pin.CollisionPair(a, b))
        self.n_self = len(self.self_pairs)
        for g in range(n):
            for k in range(len(self.object_ids)):
                geoms.addCollisionPair(pin.CollisionPair(g, n + k))
        self.geoms, self.geom_data = geoms, pin.GeometryData(geoms)
        for k in range(self.n_self, len(geoms.collisionPairs)):
            self.geom_data.collisionRequests[k].enable_contact = True

    def _pair_name(self, k: int) -> str:
        pair = self.geoms.collisionPairs[k]
        names = []
        for g in (pair.first, pair.second):
            obj = self.geoms.geometryObjects[g]
            names.append(
                obj.name
                if obj.name.startswith("scene:")
                else self.model.frames[obj.parentFrame].name
            )
        return "–".join(n.removeprefix("scene:") for n in names)

    def is_free(self, state: ArrayLike) -> bool:
        """Whether the state touches neither the scene nor itself."""
        q = self.configuration(state)
        return not pin.computeCollisions(self.model, self.data, self.geoms, self.geom_data, q, True)

    def contacts(self, state: ArrayLike) -> tuple[list[str], list[str], float]:
        """Self pairs and scene pairs in contact at `state`, and the deepest scene penetration."""
        q = self.configuration(state)
        pin.computeCollisions(self.model, self.data, self.geoms, self.geom_data, q, False)
        own, scene, depth = [], [], 0.0
        for k, result in enumerate(self.geom_data.collisionResults):
            if not result.isCollision():
                continue
            if k < self.n_self:
                own.append(self._pair_name(k))
            else:
                scene.append(self._pair_name(k))
                for contact in result.getContacts():
                    depth = max(depth, abs(float(contact.penetration_depth)))
        return own, scene, depth

    def scene_clearance(self, state: ArrayLike) -> float:
        """The least distance between the robot and the scene at `state` (coal; ∞ without
        scene objects)."""
        q = self.configuration(state)
        pin.computeDistances(self.model, self.data, self.geoms, self.geom_data, q)
        results = self.geom_data.distanceResults
        return min((results[k].min_distance for k in range(self.n_self, len(results))),
                   default=float("inf"))  # fmt: skip

    def base_clear(self) -> bool:
        """Whether the body that stands still (fixed base, or a planar base at rest) is clear of
        the scene: else no state is free."""
        q = self.configuration(np.zeros(len(self.lower)))
        pin.computeCollisions(self.model, self.data, self.geoms, self.geom_data, q, False)
        standing = 1 if self.planar else 0
        for k in range(self.n_self, len(self.geoms.collisionPairs)):
            robot_geom = self.geoms.collisionPairs[k].first
            hit = self.geom_data.collisionResults[k].isCollision()
            if hit and self.geom_body[robot_geom] == standing:
                return False
        return True

    # --- paths ---------------------------------------------------------------------------------

    def within_limits(self, states: FloatArray) -> NDArray[np.bool_]:
        """Per state, whether every planning joint lies within its limits."""
        states = np.atleast_2d(states)
        ok = (states >= self.lower - LIMIT_TOLERANCE) & (states <= self.upper + LIMIT_TOLERANCE)
        return np.all(ok, axis=1)

    def interpolate(self, path: FloatArray) -> FloatArray:
        """The dense samples of a path of key states (straight segments, finer than the paper)."""
        path = np.atleast_2d(np.asarray(path, dtype=float))
        out = [path[:1]]
        for a, b in itertools.pairwise(path):
            delta = b - a
            if self.planar:
                delta[2] = (delta[2] + np.pi) % (2 * np.pi) - np.pi
                move = np.concatenate(
                    [[np.hypot(delta[0], delta[1]) / BASE_STEP], np.abs(delta[2:]) / self.steps[2:]]
                )
            else:
                move = np.abs(delta) / self.steps
            n = max(1, int(np.ceil(float(move.max()) - 1e-12)))
            t = np.arange(1, n + 1)[:, None] / n
            out.append(a + t * delta)
        return np.concatenate(out)

    def check_path(self, path: FloatArray) -> PathVerdict:
        """Check every dense sample of `path` in the current scene."""
        dense = self.interpolate(path)
        verdict = PathVerdict(samples=len(dense))
        verdict.limit_samples = int(np.sum(~self.within_limits(dense)))
        for state in dense:
            if self.is_free(state):
                continue
            own, scene, depth = self.contacts(state)
            verdict.self_samples += bool(own)
            verdict.scene_samples += bool(scene)
            verdict.self_pairs.update(own)
            verdict.scene_pairs.update(scene)
            verdict.max_depth = max(verdict.max_depth, depth)
        return verdict
