"""The dense check of the MBM Panda: `dense_mesh.MeshChecker` with the scene's word on pairs.

It shares no code with the service. The robot is read by Pinocchio from `robot/panda.urdf` with
its collision meshes (coal BVH models) and `robot/panda.srdf` (its disabled pairs are not
checked); the planning joints are the seven arm joints, the finger joints being fixed in this
URDF. Per scene, the pairs its `allowed_collision_matrix` allows are not checked either: two
links (a self pair), or a link and an object (a scene pair). Everything else is as in
`dense_mesh`: samples 4× finer than the paper's steps, no padding, URDF joint limits.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from coal_geometry import quaternion_placement as placement
from coal_geometry import scene_geometry
from dense_mesh import FloatArray, MeshChecker
from mbm_problems import ARM_JOINTS
from mbm_tally import Tally
from robot_description import RobotDescription


def panda_description(robot_dir: Path) -> RobotDescription:
    """The MBM Panda for the dense check: URDF, SRDF, meshes below `robot_dir`, arm joints."""
    return RobotDescription(
        urdf_path=robot_dir / "panda.urdf",
        package_dir=robot_dir,  # `package://meshes/…` resolves to robot_dir/meshes/…
        joint_names=ARM_JOINTS,
        srdf_path=robot_dir / "panda.srdf",
    )


class SceneChecker(MeshChecker):
    """The dense check of one robot in one scene at a time, honouring the scene's allowed pairs."""

    def __init__(self, robot: RobotDescription) -> None:
        self.allowed: set[frozenset[str]] = set()
        super().__init__(robot)
        self.robot_self_pairs = list(self.self_pairs)  # the URDF's and the SRDF's word

    def link_of(self, geom: int) -> str:
        """The link a robot geometry belongs to."""
        return str(self.model.frames[self.robot_geoms.geometryObjects[geom].parentFrame].name)

    def set_scene(
        self, objects: Iterable[Mapping[str, Any]], allowed: set[frozenset[str]] | None = None
    ) -> None:
        """Check against these objects from now on, skipping the pairs `allowed` names."""
        self.allowed = set(allowed or ())
        if hasattr(self, "robot_self_pairs"):  # the base class's constructor calls this first
            self.self_pairs = [
                (a, b)
                for a, b in self.robot_self_pairs
                if frozenset((self.link_of(a), self.link_of(b))) not in self.allowed
            ]
        geoms = pin.GeometryModel()
        for obj in self.robot_geoms.geometryObjects:
            geoms.addGeometryObject(obj)
        self.object_ids: list[str] = []
        for obj in objects:
            geoms.addGeometryObject(
                pin.GeometryObject(
                    f"scene:{obj['id']}", 0, 0, placement(obj.get("pose")), scene_geometry(obj)
                )
            )
            self.object_ids.append(str(obj["id"]))
        for a, b in self.self_pairs:
            geoms.addCollisionPair(pin.CollisionPair(a, b))
        self.n_self = len(self.self_pairs)
        n = len(self.robot_geoms.geometryObjects)
        for g in range(n):
            for k, object_id in enumerate(self.object_ids):
                if frozenset((self.link_of(g), object_id.split("#")[0])) not in self.allowed:
                    geoms.addCollisionPair(pin.CollisionPair(g, n + k))
        self.geoms, self.geom_data = geoms, pin.GeometryData(geoms)
        for k in range(self.n_self, len(geoms.collisionPairs)):
            self.geom_data.collisionRequests[k].enable_contact = True


def path_length(states: FloatArray) -> float:
    """The joint-space length of a path of key states (sum of Euclidean steps)."""
    return float(np.linalg.norm(np.diff(states, axis=0), axis=1).sum())


DUMP: list[Path] = []  # where to append the paths that collide (`--dump-contacts`)


def check_path(
    tally: Tally,
    checker: SceneChecker,
    states: FloatArray,
    ends: tuple[FloatArray, FloatArray],
    label: str = "",
) -> None:
    """Dense-check a returned path in the checker's scene, and that it runs between `ends`;
    a path that collides is appended to `DUMP[0]` (JSON lines) when set, with `label`."""
    verdict = checker.check_path(states)
    if DUMP and (verdict.collides or verdict.self_collides):
        with DUMP[0].open("a", encoding="utf-8") as out:
            line = {"label": label, "states": np.asarray(states).tolist(),
                    "pairs": dict(verdict.scene_pairs + verdict.self_pairs)}  # fmt: skip
            out.write(json.dumps(line) + "\n")
    counts = tally.counts
    counts["paths"] += 1
    counts["dense_samples"] += verdict.samples
    counts["collisions"] += verdict.collides
    counts["self_collisions"] += verdict.self_collides
    counts["limit_violations"] += verdict.limit_samples > 0
    errors = np.abs(np.stack([states[0] - ends[0], states[-1] - ends[1]]))
    counts["endpoint_errors"] += bool(errors.max() > 1e-6)
    for pair, n in (verdict.scene_pairs + verdict.self_pairs).items():
        tally.notes[f"contact {pair} (depth ≤ {verdict.max_depth * 1e3:.1f} mm)"] += n
