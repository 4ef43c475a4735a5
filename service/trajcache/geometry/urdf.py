"""Robot models from URDF text: safe parsing, meshes from uploaded archives, the allowed pairs.

Planning limits: continuous joints, and revolute joints whose range is wider than a full turn
(e.g. the ±2π of many arms), are planned in a 2π window, [−π, π] whenever the URDF allows it.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import re
import stat
import tarfile
import xml.etree.ElementTree as ET
import zipfile
import zlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import defusedxml.ElementTree as DefusedET
import fcl
import numpy as np
import trimesh
from defusedxml import DefusedXmlException
from numpy.typing import NDArray
from yourdfpy import URDF
from yourdfpy.urdf import filename_handler_null

from trajcache.geometry.errors import (
    GeometryError,
    MeshError,
    RobotModelError,
    UnsafePathError,
)
from trajcache.geometry.kinematics import element_transforms, link_transforms
from trajcache.geometry.robot import BaseType, CollisionElement, KinematicJoint, RobotModel
from trajcache.geometry.shapes import FloatArray, Shape, ShapeKind

MiB = 1024 * 1024
DEFAULT_JOINT_VELOCITY = 3.14
BASE_VELOCITY = (0.5, 0.5, 1.0)
MOVABLE = ("revolute", "continuous", "prismatic")
_JOINT_TYPES = (*MOVABLE, "fixed", "floating", "planar")
_GEOMETRY_ATTRS = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length")}
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")
_REQUEST = fcl.CollisionRequest()
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


def unpack_archive(
    data: bytes, *, max_entries: int = 1000, max_total_bytes: int = 64 * MiB
) -> dict[str, bytes]:
    """Unpack a zip or (compressed) tar archive into {normalised relative path: content}."""
    buffer = io.BytesIO(data)
    try:
        if data[:4] in (b"PK\x03\x04", b"PK\x05\x06"):
            with zipfile.ZipFile(buffer) as archive:
                return _unpack_zip(archive, max_entries, max_total_bytes)
        with tarfile.open(fileobj=buffer, mode="r:*") as tar:
            return _unpack_tar(tar, max_entries, max_total_bytes)
    except GeometryError:
        raise
    except (tarfile.TarError, zipfile.BadZipFile, zlib.error, EOFError, OSError) as exc:
        raise RobotModelError(f"unreadable archive (expected zip or tar): {exc}") from exc
    except (RuntimeError, NotImplementedError) as exc:  # encrypted or unsupported compression
        raise RobotModelError(f"unsupported archive entry: {exc}") from exc


def _unpack_zip(archive: zipfile.ZipFile, max_entries: int, max_total: int) -> dict[str, bytes]:
    infos = archive.infolist()
    if len(infos) > max_entries:
        raise RobotModelError(f"archive has {len(infos)} entries, at most {max_entries} allowed")
    out: dict[str, bytes] = {}
    for info in infos:
        if stat.S_ISLNK(info.external_attr >> 16):
            raise UnsafePathError(f"archive entry {info.filename!r} is a symbolic link")
        path = normalise_path(info.filename, "archive entry")
        if info.is_dir():
            continue
        with archive.open(info) as fh:
            _store(out, path, fh.read(max_total - sum(map(len, out.values())) + 1), max_total)
    return out


def _unpack_tar(tar: tarfile.TarFile, max_entries: int, max_total: int) -> dict[str, bytes]:
    out: dict[str, bytes] = {}
    for count, member in enumerate(tar, start=1):
        if count > max_entries:
            raise RobotModelError(f"archive has more than {max_entries} entries")
        if member.issym() or member.islnk():
            raise UnsafePathError(f"archive entry {member.name!r} is a link")
        path = normalise_path(member.name, "archive entry")
        if member.isdir():
            continue
        if not member.isfile():
            raise UnsafePathError(f"archive entry {member.name!r} is not a regular file")
        if member.size + sum(map(len, out.values())) > max_total:
            raise RobotModelError(f"archive content exceeds {max_total} bytes")
        fh = tar.extractfile(member)
        _store(out, path, fh.read() if fh is not None else b"", max_total)
    return out


def _store(out: dict[str, bytes], path: str, content: bytes, max_total: int) -> None:
    if path in out:
        raise RobotModelError(f"archive contains {path!r} twice")
    out[path] = content
    if sum(map(len, out.values())) > max_total:
        raise RobotModelError(f"archive content exceeds {max_total} bytes")


def normalise_path(path: str, what: str) -> str:
    """Normalise a relative path ('/'-separated, no '.'/'..'); raise UnsafePathError on escapes."""
    path = path.replace("\\", "/")
    if path.startswith("/") or _SCHEME.match(path):
        raise UnsafePathError(f"{what} {path!r} is an absolute path or URL")
    parts: list[str] = []
    for part in path.split("/"):
        if part == "..":
            if not parts:
                raise UnsafePathError(f"{what} {path!r} escapes the uploaded files")
            parts.pop()
        elif part not in ("", "."):
            parts.append(part)
    if not parts:
        raise UnsafePathError(f"{what} {path!r} is empty")
    return "/".join(parts)


class _MeshResolver:
    """Finds mesh URIs in the uploaded files and loads them once each."""

    def __init__(self, files: Mapping[str, bytes]) -> None:
        self.files = {normalise_path(k, "file"): v for k, v in files.items()}
        self.used: dict[str, str] = {}  # path → sha256 of the files actually referenced
        self._meshes: dict[str, tuple[FloatArray, np.ndarray]] = {}

    def resolve(self, uri: str) -> str:
        """Path in `files` of a `package://` or relative mesh URI."""
        uri = uri.strip()
        if uri.lower().startswith("package://"):
            package, _, sub = uri[len("package://") :].partition("/")
            sub = normalise_path(sub, f"mesh URI {uri!r}: path")
            candidates = [sub, f"{package}/{sub}"]
        elif _SCHEME.match(uri) or uri.replace("\\", "/").startswith("/"):
            raise UnsafePathError(
                f"mesh URI {uri!r} is absolute or uses a scheme other than package://; "
                "only files inside the upload can be referenced"
            )
        else:
            candidates = [normalise_path(uri, "mesh URI")]
        for path in candidates:
            if path in self.files:
                return path
        raise MeshError(f"mesh {uri!r} not found in the uploaded files (tried {candidates})")

    def shape(self, uri: str, scale: Any) -> Shape:
        """Mesh shape of `uri`, scaled."""
        path = self.resolve(uri)
        if path not in self._meshes:
            data = self.files[path]
            self.used[path] = hashlib.sha256(data).hexdigest()
            kind = path.rsplit(".", 1)[-1].lower() if "." in path else ""
            try:
                mesh = trimesh.load(io.BytesIO(data), file_type=kind, force="mesh")
            except Exception as exc:
                raise MeshError(f"mesh {uri!r} is unreadable: {exc}") from exc
            if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
                raise MeshError(f"mesh {uri!r} has no triangles")
            vertices = np.asarray(mesh.vertices, dtype=float)
            self._meshes[path] = (vertices, np.asarray(mesh.faces, dtype=np.int64))
        vertices, faces = self._meshes[path]
        factor = np.ones(3) if scale is None else np.broadcast_to(np.asarray(scale, float), 3)
        return Shape(kind=ShapeKind.MESH, vertices=vertices * factor, faces=faces)


def _parse(urdf: str) -> Any:
    """yourdfpy robot of `urdf`, after refusing DTDs/entities and checking the structure."""
    urdf = urdf.strip()
    try:
        root = DefusedET.fromstring(urdf, forbid_dtd=True)
    except DefusedXmlException as exc:
        raise RobotModelError(
            f"URDF must not contain DOCTYPE or ENTITY declarations ({exc!r})"
        ) from exc
    except ET.ParseError as exc:
        raise RobotModelError(f"malformed URDF XML: {exc}") from exc
    _check_structure(root)
    text = re.sub(r"^\s*<\?xml[^>]*\?>", "", urdf)  # bytes below are UTF-8 whatever it said
    try:
        return URDF.load(
            io.BytesIO(text.encode("utf-8")),
            build_scene_graph=False,
            build_collision_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
            filename_handler=filename_handler_null,
        ).robot
    except Exception as exc:
        raise RobotModelError(f"invalid URDF: {type(exc).__name__}: {exc}") from exc


def _check_structure(root: ET.Element) -> None:
    if root.tag != "robot":
        raise RobotModelError(f"URDF root element is <{root.tag}>, expected <robot>")
    if not root.get("name"):
        raise RobotModelError("the <robot> element has no name attribute")
    links = root.findall("link")
    if not links:
        raise RobotModelError("URDF has no <link> elements")
    names = [link.get("name") or "" for link in links]
    if "" in names:
        raise RobotModelError("a <link> has no name attribute")
    if len(set(names)) != len(names):
        raise RobotModelError(
            f"duplicate link names: {sorted({n for n in names if names.count(n) > 1})}"
        )
    for link, name in zip(links, names, strict=True):
        for geometry in (c.find("geometry") for c in link.findall("collision")):
            if geometry is None or len(geometry) == 0:
                raise RobotModelError(f"a <collision> of link {name!r} has no <geometry>")
            tag, attrs = geometry[0].tag, geometry[0].attrib
            needed = _GEOMETRY_ATTRS.get(tag, ("filename",) if tag == "mesh" else None)
            if needed is None:
                raise RobotModelError(f"link {name!r}: collision geometry <{tag}> is not supported")
            if missing := [a for a in needed if a not in attrs]:
                raise RobotModelError(f"link {name!r}: <{tag}> lacks {', '.join(missing)}")
    seen: set[str] = set()
    for joint in root.findall("joint"):
        jname = joint.get("name") or ""
        if not jname or jname in seen:
            raise RobotModelError(f"a <joint> has a missing or duplicate name: {jname!r}")
        seen.add(jname)
        if joint.get("type") not in _JOINT_TYPES:
            raise RobotModelError(f"joint {jname!r} has unknown type {joint.get('type')!r}")
        for end in ("parent", "child"):
            element = joint.find(end)
            link_name = element.get("link") if element is not None else None
            if link_name not in names:
                raise RobotModelError(f"joint {jname!r}: {end} link {link_name!r} does not exist")


def _topology(robot: Any) -> tuple[list[str], list[Any]]:
    """Links (root first, depth-first) and joints (parent before child) of a single tree."""
    parent_joint: dict[str, Any] = {}
    children: dict[str, list[Any]] = {}
    for joint in robot.joints:
        if joint.child in parent_joint:
            other = parent_joint[joint.child].name
            raise RobotModelError(
                f"link {joint.child!r} has two parent joints ({other!r}, {joint.name!r})"
            )
        parent_joint[joint.child] = joint
        children.setdefault(joint.parent, []).append(joint)
    roots = [link.name for link in robot.links if link.name not in parent_joint]
    if not roots:
        raise RobotModelError("URDF has no root link: its joints form a cycle")
    if len(roots) > 1:
        raise RobotModelError(f"URDF has several root links {roots}; it must be a single tree")
    links: list[str] = []
    joints: list[Any] = []
    stack = [roots[0]]
    while stack:
        name = stack.pop()
        links.append(name)
        if name != roots[0]:
            joints.append(parent_joint[name])
        stack.extend(j.child for j in reversed(children.get(name, [])))
    if len(links) < len(robot.links):
        cyclic = sorted({link.name for link in robot.links} - set(links))
        raise RobotModelError(f"links {cyclic} form a cycle (not reachable from {roots[0]!r})")
    return links, joints


def _joint_limits(joint: Any) -> tuple[float, float, float]:
    """Planning (lower, upper, velocity) of a movable joint."""
    limit = joint.limit
    velocity = getattr(limit, "velocity", None)
    if velocity is None or not math.isfinite(velocity) or velocity <= 0:
        velocity = DEFAULT_JOINT_VELOCITY
    if joint.type == "continuous":
        return -math.pi, math.pi, velocity
    if limit is None:
        raise RobotModelError(f"{joint.type} joint {joint.name!r} has no <limit>")
    lower = 0.0 if limit.lower is None else float(limit.lower)
    upper = 0.0 if limit.upper is None else float(limit.upper)
    if not (math.isfinite(lower) and math.isfinite(upper)) or lower > upper:
        raise RobotModelError(f"joint {joint.name!r} has invalid limits [{lower}, {upper}]")
    if joint.type == "revolute" and upper - lower > 2 * math.pi + 1e-9:
        lower = min(max(-math.pi, lower), upper - 2 * math.pi)
        upper = lower + 2 * math.pi
    return lower, upper, velocity


def _planning_joints(robot: Any, joint_names: Sequence[str] | None) -> list[str]:
    movable = [j.name for j in robot.joints if j.type in MOVABLE]
    if joint_names is None:
        return movable
    if isinstance(joint_names, str):
        raise RobotModelError("joint_names must be a list of joint names, not a string")
    names = list(joint_names)
    all_joints = {j.name for j in robot.joints}
    if unknown := [n for n in names if n not in all_joints]:
        raise RobotModelError(f"unknown joint names {unknown}; movable joints are {movable}")
    if fixed := [n for n in names if n not in movable]:
        raise RobotModelError(f"joints {fixed} are not movable and cannot be planned")
    if len(set(names)) != len(names):
        raise RobotModelError(f"joint names are repeated: {names}")
    return names


def _kinematic_joints(
    ordered: list[Any], links: list[str], planning: list[str], offset: int
) -> tuple[list[KinematicJoint], list[tuple[float, float, float]]]:
    """KinematicJoints in topological order and the planning limits in `planning` order."""
    link_index = {name: i for i, name in enumerate(links)}
    limits: dict[str, tuple[float, float, float]] = {}
    defaults: dict[str, float] = {}
    for joint in ordered:
        if joint.type in ("floating", "planar"):
            raise RobotModelError(
                f"joint {joint.name!r} is {joint.type}, which is not supported "
                "(use base='planar' for a mobile base)"
            )
        if joint.type in MOVABLE:
            limits[joint.name] = lo, hi, _ = _joint_limits(joint)
            defaults[joint.name] = min(max(0.0, lo), hi)
    for joint in ordered:
        if joint.mimic is None:
            continue
        if joint.name in planning or joint.mimic.joint in planning:
            raise RobotModelError(
                f"joint {joint.name!r} mimics {joint.mimic.joint!r}; mimic joints are not "
                "supported unless both are left out of the planning joints"
            )
        lo, hi, _ = limits[joint.name]
        value = (joint.mimic.multiplier or 1.0) * defaults.get(joint.mimic.joint, 0.0)
        defaults[joint.name] = min(max(value + (joint.mimic.offset or 0.0), lo), hi)
    result = []
    for joint in ordered:
        origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)
        axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), float)
        norm = float(np.linalg.norm(axis))
        if not np.all(np.isfinite(origin)) or not math.isfinite(norm):
            raise RobotModelError(f"joint {joint.name!r} has a non-finite origin or axis")
        if norm < 1e-12 and joint.type in MOVABLE:
            raise RobotModelError(f"joint {joint.name!r} has a zero axis")
        kind = joint.type if joint.type in MOVABLE else "fixed"
        index = planning.index(joint.name) + offset if joint.name in planning else -1
        result.append(
            KinematicJoint(
                name=joint.name,
                kind=kind,
                parent=link_index[joint.parent],
                child=link_index[joint.child],
                origin=origin,
                axis=axis / norm if norm >= 1e-12 else np.array([1.0, 0.0, 0.0]),
                index=index,
                default=defaults.get(joint.name, 0.0),
            )
        )
    return result, [limits[name] for name in planning]


def _elements(robot: Any, links: list[str], resolver: _MeshResolver) -> list[CollisionElement]:
    by_name = {link.name: link for link in robot.links}
    elements = []
    for index, name in enumerate(links):
        for collision in by_name[name].collisions:
            geometry = collision.geometry
            origin = np.eye(4) if collision.origin is None else np.asarray(collision.origin, float)
            if not np.all(np.isfinite(origin)):
                raise RobotModelError(f"link {name!r}: collision origin is not finite")
            try:
                if geometry.box is not None:
                    shape = Shape(ShapeKind.BOX, tuple(float(v) for v in geometry.box.size))
                elif geometry.sphere is not None:
                    shape = Shape(ShapeKind.SPHERE, (float(geometry.sphere.radius),))
                elif geometry.cylinder is not None:
                    size = (float(geometry.cylinder.radius), float(geometry.cylinder.length))
                    shape = Shape(ShapeKind.CYLINDER, size)
                else:
                    shape = resolver.shape(geometry.mesh.filename, geometry.mesh.scale)
            except RobotModelError:
                raise
            except GeometryError as exc:
                raise RobotModelError(f"link {name!r}: {exc}") from exc
            elements.append(CollisionElement(link=index, shape=shape, origin=origin))
    return elements


def _model_id(urdf: str, base: BaseType, joint_names: list[str], files: dict[str, str]) -> str:
    text = urdf.replace("\r\n", "\n").strip()
    payload = {"urdf": text, "base": base.value, "joint_names": joint_names, "files": files}
    canonical = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def load_robot_model(
    urdf: str,
    *,
    files: Mapping[str, bytes] | None = None,
    base: BaseType | str = "fixed",
    joint_names: Sequence[str] | None = None,
    name: str | None = None,
    acm_samples: int = 2000,
    seed: int = 0,
    allowed_pairs: Iterable[Sequence[int]] | None = None,
) -> RobotModel:
    """Build a RobotModel from URDF text and its mesh files; raise RobotModelError if unusable."""
    try:
        base_type = BaseType(base)
    except ValueError as exc:
        raise RobotModelError(f"unknown base type {base!r}; expected 'fixed' or 'planar'") from exc
    robot = _parse(urdf)
    links, ordered = _topology(robot)
    planning = _planning_joints(robot, joint_names)
    planar = base_type is BaseType.PLANAR
    joints, limits = _kinematic_joints(ordered, links, planning, 3 if planar else 0)
    resolver = _MeshResolver(files or {})
    elements = _elements(robot, links, resolver)
    base_limits = [(-math.inf, math.inf, v) for v in BASE_VELOCITY[:2]]
    base_limits.append((-math.pi, math.pi, BASE_VELOCITY[2]))
    table = np.array((base_limits if planar else []) + limits, dtype=float).reshape(-1, 3)
    model = RobotModel(
        model_id=_model_id(urdf, base_type, planning, dict(sorted(resolver.used.items()))),
        name=name or robot.name,
        base=base_type,
        joint_names=tuple(planning),
        link_names=tuple(links),
        joints=tuple(joints),
        elements=tuple(elements),
        lower=table[:, 0].copy(),
        upper=table[:, 1].copy(),
        velocity_limits=table[:, 2].copy(),
    )
    if allowed_pairs is not None:  # stored with the model: skip the sampling
        pairs = frozenset((min(int(a), int(b)), max(int(a), int(b))) for a, b in allowed_pairs)
        return replace(model, allowed_pairs=pairs)
    return replace(model, allowed_pairs=allowed_collision_pairs(model, acm_samples, seed))


def _adjacent_pairs(model: RobotModel) -> set[tuple[int, int]]:
    """Link pairs joined by one planning joint, treating fixed and held joints as rigid."""
    group = list(range(len(model.link_names)))

    def find(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i

    for joint in model.joints:
        if joint.index < 0:
            group[find(joint.child)] = find(joint.parent)
    members: dict[int, list[int]] = {}
    for link in range(len(group)):
        members.setdefault(find(link), []).append(link)
    pairs = {(a, b) for body in members.values() for a in body for b in body if a < b}
    for joint in model.joints:
        if joint.index >= 0:
            for a in members[find(joint.parent)]:
                pairs.update((min(a, b), max(a, b)) for b in members[find(joint.child)])
    return pairs


def allowed_collision_pairs(
    model: RobotModel, samples: int, seed: int
) -> frozenset[tuple[int, int]]:
    """Link pairs (i < j) to skip: adjacent, colliding in the default state, or never colliding.

    "Never" is judged on `samples` uniform random states within limits (none when samples is 0);
    a bounding-sphere test filters out states where a pair cannot touch before FCL runs.
    """
    geometric = [int(v) for v in model.geometric_links()]
    allowed = {p for p in _adjacent_pairs(model) if p[0] in geometric and p[1] in geometric}
    candidates = [(a, b) for a in geometric for b in geometric if a < b and (a, b) not in allowed]
    if not candidates:
        return frozenset(allowed)
    rng = np.random.default_rng(seed)
    arm = slice(model.arm_offset, model.dof)
    states = np.zeros((max(samples, 0) + 1, model.dof))
    states[0, arm] = np.clip(0.0, model.lower[arm], model.upper[arm])
    states[1:, arm] = rng.uniform(
        model.lower[arm], model.upper[arm], (states.shape[0] - 1, model.dof - model.arm_offset)
    )
    poses = element_transforms(model, link_transforms(model, states))
    centers = poses[:, :, :3, 3]
    radius = np.array([e.shape.bounding_radius() for e in model.elements])
    objects = [fcl.CollisionObject(e.shape.to_fcl(), fcl.Transform()) for e in model.elements]
    of_link: dict[int, list[int]] = {}
    for index, element in enumerate(model.elements):
        of_link.setdefault(element.link, []).append(index)
    for a, b in candidates:
        ea = np.repeat(of_link[a], len(of_link[b]))
        eb = np.tile(of_link[b], len(of_link[a]))
        gap = np.linalg.norm(centers[:, ea] - centers[:, eb], axis=-1) - radius[ea] - radius[eb]
        near = gap <= 1e-9  # (S, element pairs): only these can touch

        if _any_collision(objects, poses, ea, eb, near, np.array([0])):
            allowed.add((a, b))  # colliding in the default state: always ignored
        elif samples > 0:
            sampled = np.flatnonzero(near[1:].any(axis=1)) + 1
            if not _any_collision(objects, poses, ea, eb, near, sampled):
                allowed.add((a, b))  # never in collision across the samples
    return frozenset(allowed)


def _any_collision(
    objects: list[Any],
    poses: FloatArray,
    ea: IntArray,
    eb: IntArray,
    near: BoolArray,
    states: IntArray,
) -> bool:
    """Whether element pairs (ea[k], eb[k]) flagged in `near` collide in any of `states`."""
    for state in states:
        for i, j in zip(ea[near[state]], eb[near[state]], strict=True):
            for e in (i, j):
                pose = poses[state, e]
                objects[e].setTransform(fcl.Transform(pose[:3, :3], pose[:3, 3]))
            if fcl.collide(objects[i], objects[j], _REQUEST, fcl.CollisionResult()) > 0:
                return True
    return False
