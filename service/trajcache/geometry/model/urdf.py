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
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import defusedxml.ElementTree as DefusedET
import numpy as np
import trimesh
from defusedxml import DefusedXmlException
from yourdfpy import URDF
from yourdfpy.urdf import filename_handler_null

from trajcache.geometry.errors import (
    GeometryError,
    MeshError,
    RobotModelError,
    UnsafePathError,
)
from trajcache.geometry.model.robot import BaseType, CollisionElement, KinematicJoint, RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.srdf import Srdf, group_joints, parse_srdf

MiB = 1024 * 1024
DEFAULT_JOINT_VELOCITY = 3.14
BASE_VELOCITY = (0.5, 0.5, 1.0)
MOVABLE = ("revolute", "continuous", "prismatic")
_JOINT_TYPES = (*MOVABLE, "fixed", "floating", "planar")
_GEOMETRY_ATTRS = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length")}
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


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


def _joint_limits(joint: Any) -> tuple[float, float, float] | None:
    """Planning (lower, upper, velocity) of a movable joint; None for a prismatic joint without
    limits (it can be held, not planned). A revolute joint without limits turns freely."""
    limit = joint.limit
    velocity = getattr(limit, "velocity", None)
    if velocity is None or not math.isfinite(velocity) or velocity <= 0:
        velocity = DEFAULT_JOINT_VELOCITY
    unbounded = limit is None or (limit.lower is None and limit.upper is None)
    if joint.type == "continuous" or (joint.type == "revolute" and unbounded):
        return -math.pi, math.pi, velocity
    if unbounded:
        return None
    lower = 0.0 if limit.lower is None else float(limit.lower)
    upper = 0.0 if limit.upper is None else float(limit.upper)
    if not (math.isfinite(lower) and math.isfinite(upper)) or lower > upper:
        raise RobotModelError(f"joint {joint.name!r} has invalid limits [{lower}, {upper}]")
    if joint.type == "revolute" and upper - lower > 2 * math.pi + 1e-9:
        lower = min(max(-math.pi, lower), upper - 2 * math.pi)
        upper = lower + 2 * math.pi
    return lower, upper, velocity


def _planning_joints(
    ordered: list[Any],
    joint_names: Sequence[str] | None,
    group: str | None,
    srdf: Srdf | None,
    warnings: list[str],
) -> list[str]:
    """The planning joints: listed, an SRDF group's movable joints, or every movable joint that
    does not mimic another (both in the URDF's order, `ordered` being the file's joints)."""
    movable = [j.name for j in ordered if j.type in MOVABLE]
    if group is not None:
        if joint_names is not None:
            raise RobotModelError("give either joint_names or group, not both")
        if srdf is None:
            raise RobotModelError(f"group {group!r} needs an SRDF that defines it")
        parent_of = {j.child: (j.name, j.parent) for j in ordered}
        members, skipped = group_joints(
            srdf, group, parent_of=parent_of, joints=[j.name for j in ordered]
        )
        warnings += skipped
        names = [n for n in movable if n in members]
        if not names:
            raise RobotModelError(f"SRDF group {group!r} has no movable joints")
        return names
    if joint_names is None:
        return [j.name for j in ordered if j.type in MOVABLE and j.mimic is None]
    if isinstance(joint_names, str):
        raise RobotModelError("joint_names must be a list of joint names, not a string")
    names = list(joint_names)
    all_joints = {j.name for j in ordered}
    if unknown := [n for n in names if n not in all_joints]:
        raise RobotModelError(f"unknown joint names {unknown}; movable joints are {movable}")
    if fixed := [n for n in names if n not in movable]:
        raise RobotModelError(f"joints {fixed} are not movable and cannot be planned")
    if len(set(names)) != len(names):
        raise RobotModelError(f"joint names are repeated: {names}")
    return names


def _held_values(
    ordered: list[Any],
    planning: list[str],
    limits: Mapping[str, tuple[float, float, float] | None],
    joint_values: Mapping[str, float] | str | None,
    srdf: Srdf | None,
) -> dict[str, float]:
    """Values of the movable joints outside the planning group.

    Each is 0 clipped into its limits unless `joint_values` gives it (by name, or an SRDF
    group_state's name); a mimic joint follows its leader (multiplier · leader + offset). One
    that follows a planning joint moves with it in every state (`_check_planned_mimic`).
    """
    by_name = {j.name: j for j in ordered}
    followers = {j.name: j.mimic for j in ordered if j.type in MOVABLE and j.mimic is not None}
    for name, mimic in followers.items():
        leader = by_name.get(mimic.joint)
        if leader is None or leader.type not in MOVABLE:
            raise RobotModelError(f"joint {name!r} mimics {mimic.joint!r}, not a movable joint")
        if name in planning:
            raise RobotModelError(
                f"joint {name!r} mimics {mimic.joint!r}: plan with {mimic.joint!r}, not with it"
            )
        if mimic.joint in planning:
            _check_planned_mimic(by_name, name, mimic)
    values: dict[str, float] = {}
    for joint in ordered:
        if joint.type in MOVABLE and joint.name not in planning and joint.name not in followers:
            bounds = limits[joint.name]
            values[joint.name] = 0.0 if bounds is None else min(max(0.0, bounds[0]), bounds[1])
    given: Mapping[str, float]
    if isinstance(joint_values, str):
        if srdf is None:
            raise RobotModelError(f"joint_values {joint_values!r} names a group_state: no SRDF")
        state = srdf.state(joint_values)
        given = {k: v for k, v in state.values.items() if k not in planning}
    else:
        given = joint_values or {}
    for name, value in given.items():
        if name not in by_name:
            raise RobotModelError(f"joint_values: unknown joint {name!r}")
        if name in planning:
            raise RobotModelError(
                f"joint_values: {name!r} is a planning joint; its value comes with each state"
            )
        if name in followers:
            raise RobotModelError(
                f"joint_values: {name!r} mimics {followers[name].joint!r}; give that joint"
            )
        if name not in values:
            raise RobotModelError(f"joint_values: {name!r} is a fixed joint")
        value = float(value)
        bounds = limits[name]
        if not math.isfinite(value):
            raise RobotModelError(f"joint_values: {name!r} is not finite")
        if bounds is not None and not bounds[0] - 1e-9 <= value <= bounds[1] + 1e-9:
            raise RobotModelError(
                f"joint_values: {name} = {value:.6g} not in [{bounds[0]:.6g}, {bounds[1]:.6g}]"
            )
        values[name] = value
    pending = {n: m for n, m in followers.items() if m.joint not in planning}
    while pending:
        ready = {n: m for n, m in pending.items() if m.joint in values}
        if not ready:
            raise RobotModelError(f"mimic joints {sorted(pending)} follow each other in a cycle")
        for name, mimic in ready.items():
            multiplier = 1.0 if mimic.multiplier is None else float(mimic.multiplier)
            offset = 0.0 if mimic.offset is None else float(mimic.offset)
            values[name] = multiplier * values[mimic.joint] + offset
            del pending[name]
    return values


MAX_MIMIC_MULTIPLIER = 1.0  # a planned mimic joint moves at most as far as its leader


def _check_planned_mimic(by_name: Mapping[str, Any], name: str, mimic: Any) -> None:
    """A joint that mimics a planning joint is followed when both are prismatic (a parallel
    gripper's fingers), |multiplier| ≤ 1 and neither is below the other; else RobotModelError
    names what is not supported."""
    follower, leader = by_name[name], by_name[mimic.joint]
    multiplier = 1.0 if mimic.multiplier is None else float(mimic.multiplier)
    if follower.type != "prismatic" or leader.type != "prismatic":
        raise RobotModelError(
            f"joint {name!r} mimics planning joint {mimic.joint!r}: only prismatic joints that "
            "mimic a prismatic planning joint are supported; hold both (leave them out of the "
            "planning joints)"
        )
    if not abs(multiplier) <= MAX_MIMIC_MULTIPLIER:
        raise RobotModelError(
            f"joint {name!r} mimics {mimic.joint!r} with multiplier {multiplier}: at most "
            f"{MAX_MIMIC_MULTIPLIER} in magnitude is supported for a planning joint"
        )
    parent = {j.child: j for j in by_name.values()}
    for low, high in ((follower, leader), (leader, follower)):
        link = low.parent
        while link in parent:
            if parent[link].name == high.name:
                raise RobotModelError(
                    f"joint {name!r} mimics {mimic.joint!r} on the same chain: not supported"
                )
            link = parent[link].parent


def _kinematic_joints(
    ordered: list[Any],
    links: list[str],
    planning: list[str],
    offset: int,
    held: Mapping[str, float],
    limits: Mapping[str, tuple[float, float, float] | None],
) -> list[KinematicJoint]:
    """KinematicJoints in topological order; joints outside `planning` are held at `held`."""
    link_index = {name: i for i, name in enumerate(links)}
    result = []
    for joint in ordered:
        if joint.type in ("floating", "planar"):
            raise RobotModelError(
                f"joint {joint.name!r} is {joint.type}, which is not supported "
                "(use base='planar' for a mobile base)"
            )
        origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)
        axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), float)
        norm = float(np.linalg.norm(axis))
        if not np.all(np.isfinite(origin)) or not math.isfinite(norm):
            raise RobotModelError(f"joint {joint.name!r} has a non-finite origin or axis")
        if norm < 1e-12 and joint.type in MOVABLE:
            raise RobotModelError(f"joint {joint.name!r} has a zero axis")
        kind = joint.type if joint.type in MOVABLE else "fixed"
        driver = joint.name
        if kind != "fixed" and joint.mimic is not None and joint.mimic.joint in planning:
            driver = joint.mimic.joint  # follows a planning joint: scaled in kinematics
        index = planning.index(driver) + offset if driver in planning else -1
        bounds = limits.get(joint.name)
        mimic = None
        if kind != "fixed" and joint.mimic is not None:
            multiplier = 1.0 if joint.mimic.multiplier is None else float(joint.mimic.multiplier)
            mimic = (joint.mimic.joint, multiplier, float(joint.mimic.offset or 0.0))
        result.append(
            KinematicJoint(
                name=joint.name,
                kind=kind,
                parent=link_index[joint.parent],
                child=link_index[joint.child],
                origin=origin,
                axis=axis / norm if norm >= 1e-12 else np.array([1.0, 0.0, 0.0]),
                index=index,
                default=held.get(joint.name, 0.0),
                bounds=None if bounds is None else (bounds[0], bounds[1]),
                mimic=mimic,
            )
        )
    return result


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
            elements.append(CollisionElement.placed(index, shape, origin))
    return elements


def _model_id(
    urdf: str,
    base: BaseType,
    joint_names: list[str],
    files: dict[str, str],
    srdf: str | None,
    held: Mapping[str, float],
) -> str:
    text = urdf.replace("\r\n", "\n").strip()
    payload: dict[str, Any] = {
        "urdf": text,
        "base": base.value,
        "joint_names": joint_names,
        "files": files,
    }
    if srdf is not None:  # only when given: models registered without one keep their ids
        payload["srdf"] = srdf.replace("\r\n", "\n").strip()
    if any(value != 0.0 for value in held.values()):
        payload["held"] = {name: repr(float(value)) for name, value in sorted(held.items())}
    canonical = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def load_robot_model(
    urdf: str,
    *,
    files: Mapping[str, bytes] | None = None,
    base: BaseType | str = "fixed",
    joint_names: Sequence[str] | None = None,
    group: str | None = None,
    srdf: str | None = None,
    joint_values: Mapping[str, float] | str | None = None,
    name: str | None = None,
) -> RobotModel:
    """Build a RobotModel from URDF text, its mesh files and optionally its SRDF.

    The planning joints are `joint_names`, or the SRDF group `group`, or every movable joint that
    does not mimic another. Movable joints outside them are held: at `joint_values` (by name, or
    an SRDF group_state's name), else at 0 within their limits; mimic joints follow their
    leader. RobotModelError names whatever makes the description unusable.
    """
    try:
        base_type = BaseType(base)
    except ValueError as exc:
        raise RobotModelError(f"unknown base type {base!r}; expected 'fixed' or 'planar'") from exc
    robot = _parse(urdf)
    links, ordered = _topology(robot)
    semantic = parse_srdf(srdf) if srdf is not None else None
    warnings: list[str] = []
    planning = _planning_joints(list(robot.joints), joint_names, group, semantic, warnings)
    limits = {j.name: _joint_limits(j) for j in ordered if j.type in MOVABLE}
    if unbounded := [n for n in planning if limits[n] is None]:
        raise RobotModelError(
            f"prismatic joints {unbounded} have no <limit>; they cannot be planned"
        )
    held = _held_values(ordered, planning, limits, joint_values, semantic)
    planar = base_type is BaseType.PLANAR
    joints = _kinematic_joints(ordered, links, planning, 3 if planar else 0, held, limits)
    resolver = _MeshResolver(files or {})
    elements = _elements(robot, links, resolver)
    base_limits = [(-math.inf, math.inf, v) for v in BASE_VELOCITY[:2]]
    base_limits.append((-math.pi, math.pi, BASE_VELOCITY[2]))
    planned = [limits[n] for n in planning]
    table = np.array((base_limits if planar else []) + planned, dtype=float).reshape(-1, 3)
    model = RobotModel(
        model_id=_model_id(
            urdf, base_type, planning, dict(sorted(resolver.used.items())), srdf, held
        ),
        name=name or robot.name,
        base=base_type,
        joint_names=tuple(planning),
        link_names=tuple(links),
        joints=tuple(joints),
        elements=tuple(elements),
        lower=table[:, 0].copy(),
        upper=table[:, 1].copy(),
        velocity_limits=table[:, 2].copy(),
        held_values=dict(held),
    )
    reasons = skipped_pairs(model, semantic)
    named = named_states(model, semantic) if semantic is not None else {}
    if semantic is not None:
        known = set(links)
        unknown = sorted({n for a, b, _ in semantic.disabled for n in (a, b) if n not in known})
        if unknown:
            warnings.append(f"SRDF disable_collisions name unknown links {unknown}; not applied")
    return replace(
        model,
        pair_reasons=reasons,
        named_states=named,
        warnings=tuple(warnings),
    )


def _rigid_bodies(model: RobotModel) -> list[int]:
    """Body of each link: links joined by fixed joints form one rigid body."""
    group = list(range(len(model.link_names)))

    def find(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i

    for joint in model.joints:
        if joint.kind == "fixed":
            group[find(joint.child)] = find(joint.parent)
    return [find(link) for link in range(len(group))]


def adjacent_pairs(model: RobotModel) -> set[tuple[int, int]]:
    """Link pairs (i < j, both with geometry) that are adjacent: in one rigid body (links joined
    by fixed joints), or in two bodies joined by a joint. A body without collision geometry that
    only links one parent body to one child body passes adjacency through, as a bare frame in a
    chain does; a bare body with several children joins none of them to each other."""
    body = _rigid_bodies(model)
    geometric = {int(link) for link in model.geometric_links()}
    solid = {body[link] for link in geometric}
    parent: dict[int, int] = {}
    children: dict[int, set[int]] = {}
    for joint in model.joints:
        a, b = body[joint.parent], body[joint.child]
        if a != b:
            parent[b] = a
            children.setdefault(a, set()).add(b)
    neighbours: dict[int, set[int]] = {b: set() for b in solid}
    for b in solid:
        current = b
        while current in parent:
            up = parent[current]
            if up in solid:
                neighbours[b].add(up)
                break
            if len(children.get(up, ())) != 1:
                break
            current = up
    pairs: set[tuple[int, int]] = set()
    links = sorted(geometric)
    for k, a in enumerate(links):
        for b in links[k + 1 :]:
            ba, bb = body[a], body[b]
            if ba == bb or bb in neighbours[ba] or ba in neighbours[bb]:
                pairs.add((a, b))
    return pairs


def rigid_pairs(model: RobotModel) -> set[tuple[int, int]]:
    """Link pairs (i < j, both with geometry) that no planning joint moves relative to each
    other: the planning joints above one are exactly those above the other (the base moves
    every link alike). Their contact is the same in every state, so no motion can change it."""
    parent_joint = {joint.child: joint for joint in model.joints}
    above: list[frozenset[str]] = []  # the planning-driven joints above each link
    for link in range(len(model.link_names)):
        driven: set[str] = set()
        current = link
        while current in parent_joint:
            joint = parent_joint[current]
            if joint.index >= 0:
                driven.add(joint.name)
            current = joint.parent
        above.append(frozenset(driven))
    links = [int(link) for link in model.geometric_links()]
    return {(a, b) for k, a in enumerate(links) for b in links[k + 1 :] if above[a] == above[b]}


def skipped_pairs(model: RobotModel, srdf: Srdf | None) -> dict[tuple[int, int], str]:
    """Link pairs (i < j, both with geometry) whose self-collisions are not checked, and why:
    `adjacent`, `rigid` (`rigid_pairs`) or `srdf` (the SRDF's disable_collisions). Every other
    pair is checked unless the geometry proves it free within the limits (`free_pairs`)."""
    reasons = {pair: "adjacent" for pair in adjacent_pairs(model)}
    for pair in rigid_pairs(model):
        reasons.setdefault(pair, "rigid")
    if srdf is not None:
        index = {name: i for i, name in enumerate(model.link_names)}
        geometric = {int(link) for link in model.geometric_links()}
        for link1, link2, _ in srdf.disabled:
            a, b = index.get(link1), index.get(link2)
            if a is None or b is None or a == b or a not in geometric or b not in geometric:
                continue
            reasons.setdefault((min(a, b), max(a, b)), "srdf")
    return reasons


def named_states(model: RobotModel, srdf: Srdf) -> dict[str, tuple[float, ...]]:
    """The SRDF group_states that give every planning joint a value: those values, in
    `joint_names` order (values of other joints are left out; held joints keep theirs)."""
    out: dict[str, tuple[float, ...]] = {}
    for state in srdf.states:
        if all(name in state.values for name in model.joint_names):
            out.setdefault(state.name, tuple(state.values[n] for n in model.joint_names))
    return out
