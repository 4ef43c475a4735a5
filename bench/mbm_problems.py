"""The MotionBenchMaker Panda problems as shipped: unpacked once, read from MoveIt's YAML.

The data set (`../shared/data/mbm-panda` from the repository root, see its README.md) holds
`problems.tar.bz2` (`problems/<family>_panda/sceneNNNN.yaml` + `requestNNNN.yaml`) and
`robot/` (panda.urdf, panda.srdf, meshes/collision/*.obj). The tarball is unpacked into the
user's cache directory, keyed by its content hash, so a second run reads it straight away.

Nothing here uses the service: the scene text is kept as sent to it, and read separately
(PyYAML) into the dense check's objects and allowed pairs.
- A request's start is its `start_state.joint_state` positions of the seven arm joints; its goal
  the `goal_constraints[0].joint_constraints` positions of the same joints (the finger joints are
  fixed in this URDF and are left out).
- A MoveIt primitive's `dimensions`: box (x, y, z) full sides, sphere (r), cylinder
  (height, radius); poses are `primitive_poses`, after the object's `pose` when it has one.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tarfile
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO.parent / "shared" / "data" / "mbm-panda"
ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
FAMILIES = ("bookshelf_small", "bookshelf_tall", "bookshelf_thin", "box", "cage", "table_pick",
            "table_under_pick")  # fmt: skip


@dataclass(frozen=True)
class Problem:
    """One MBM problem: its scene as sent (YAML text and parsed), start and goal (arm joints)."""

    family: str
    index: int  # the NNNN of its file names
    scene_text: str
    scene: dict[str, Any]
    start: FloatArray
    goal: FloatArray
    request_text: str = ""  # the MotionPlanRequest YAML as shipped

    @property
    def label(self) -> str:
        """`family-NNNN`, also the problem's robot id."""
        return f"{self.family}-{self.index:04d}"


def unpacked(data: Path, cache: Path | None = None) -> Path:
    """The `problems/` folder of the data set's tarball, unpacked once into the cache."""
    tarball = data / "problems.tar.bz2"
    digest = hashlib.sha256(tarball.read_bytes()).hexdigest()[:16]
    base = cache or Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "trajcache"
    target = base / f"mbm-panda-{digest}"
    if not (target / "problems").is_dir():
        base.mkdir(parents=True, exist_ok=True)
        tmp = tempfile.mkdtemp(dir=base, prefix=".unpacking-")
        try:
            with tarfile.open(tarball, "r:bz2") as archive:
                archive.extractall(tmp, filter="data")
            os.replace(tmp, target)  # atomic: a racing run finds it whole or not at all
        except OSError:
            if not (target / "problems").is_dir():
                raise
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return target / "problems"


def _request_states(request: dict[str, Any]) -> tuple[FloatArray, FloatArray]:
    joint_state = request["start_state"]["joint_state"]
    start = dict(zip(joint_state["name"], joint_state["position"], strict=True))
    constraints = request["goal_constraints"][0]["joint_constraints"]
    goal = {c["joint_name"]: c["position"] for c in constraints}
    return (
        np.array([float(start[j]) for j in ARM_JOINTS]),
        np.array([float(goal[j]) for j in ARM_JOINTS]),
    )


def load_problem(problems: Path, family: str, index: int) -> Problem:
    """Problem `index` of `family` (its folder is `<family>_panda`)."""
    folder = problems / f"{family}_panda"
    scene_text = (folder / f"scene{index:04d}.yaml").read_text(encoding="utf-8")
    request_text = (folder / f"request{index:04d}.yaml").read_text(encoding="utf-8")
    start, goal = _request_states(yaml.safe_load(request_text))
    return Problem(family, index, scene_text, yaml.safe_load(scene_text), start, goal, request_text)


def family_indices(problems: Path, family: str) -> list[int]:
    """The problem numbers of a family, in order."""
    folder = problems / f"{family}_panda"
    if not folder.is_dir():
        raise FileNotFoundError(f"no family {family!r} in {problems}")
    return sorted(int(p.stem.removeprefix("request")) for p in folder.glob("request*.yaml"))


def load_problems(problems: Path, families: list[str], per_family: int | None) -> list[Problem]:
    """The first `per_family` problems (None: all) of each family."""
    out = []
    for family in families:
        for index in family_indices(problems, family)[:per_family]:
            out.append(load_problem(problems, family, index))
    return out


# --- the scene, read for the dense check ------------------------------------------------------


def _quaternion_matrix(xyzw: list[float]) -> FloatArray:
    x, y, z, w = np.asarray(xyzw, dtype=float) / np.linalg.norm(xyzw)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def _matrix_quaternion(r: FloatArray) -> list[float]:
    w = np.sqrt(max(0.0, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    return [float(x), float(y), float(z), float(w)]


def _pose(pose: dict[str, Any] | None) -> tuple[FloatArray, FloatArray]:
    pose = pose or {}
    rotation = _quaternion_matrix(pose.get("orientation") or [0.0, 0.0, 0.0, 1.0])
    return rotation, np.asarray(pose.get("position") or [0.0, 0.0, 0.0], dtype=float)


def _size(kind: str, dims: list[float]) -> list[float]:
    if kind == "box":
        return [float(v) for v in dims[:3]]
    if kind == "sphere":
        return [float(dims[0])]
    if kind == "cylinder":  # MoveIt: (height, radius); the check's objects: (radius, length)
        return [float(dims[1]), float(dims[0])]
    raise ValueError(f"primitive type {kind!r} is not supported by the dense check")


def scene_objects(scene: dict[str, Any]) -> list[dict[str, Any]]:
    """The scene's primitives as the dense check's objects: id, type, size and world pose."""
    out = []
    for obj in (scene.get("world") or {}).get("collision_objects") or []:
        if obj.get("meshes") or obj.get("planes"):
            raise ValueError(f"object {obj['id']!r}: meshes and planes are not supported here")
        r0, p0 = _pose(obj.get("pose"))
        prims, poses = obj.get("primitives") or [], obj.get("primitive_poses") or []
        for k, (prim, pose) in enumerate(zip(prims, poses, strict=True)):
            r1, p1 = _pose(pose)
            kind = str(prim["type"]).lower()
            out.append({
                "id": obj["id"] if len(prims) == 1 else f"{obj['id']}#{k}",
                "type": kind,
                "size": _size(kind, prim["dimensions"]),
                "pose": {"position": (p0 + r0 @ p1).tolist(),
                         "orientation": _matrix_quaternion(r0 @ r1)},
            })  # fmt: skip
    return out


def allowed_pairs(scene: dict[str, Any]) -> set[frozenset[str]]:
    """The pairs of names (links or objects) the scene's allowed_collision_matrix allows."""
    acm = scene.get("allowed_collision_matrix") or {}
    names = acm.get("entry_names") or []
    out = set()
    for a, row in zip(names, acm.get("entry_values") or [], strict=True):
        for b, allowed in zip(names, row, strict=True):
            if allowed and a != b:
                out.add(frozenset((a, b)))
    return out


# --- the robot ---------------------------------------------------------------------------------


def clamp(state: FloatArray, lower: FloatArray, upper: FloatArray) -> tuple[FloatArray, bool]:
    """The state within [lower, upper], and whether it had to move."""
    out = np.clip(state, lower, upper)
    return out, bool(np.any(out != state))
