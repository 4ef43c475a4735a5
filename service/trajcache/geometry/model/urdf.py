"""Robot models from URDF text: safe parsing, the tree of links and joints, collision elements.

The pieces are the joints' (`joints.py`: planning limits, planning joints, held and mimic
values), the uploaded files' (`files.py`: archives, meshes) and the unchecked pairs'
(`pairs.py`); `load_robot_model` puts them together and gives the model its id.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import defusedxml.ElementTree as DefusedET
import numpy as np
from defusedxml import DefusedXmlException
from yourdfpy import URDF
from yourdfpy.urdf import filename_handler_null

from trajcache.geometry.errors import GeometryError, RobotModelError
from trajcache.geometry.model.files import MeshResolver
from trajcache.geometry.model.joints import (
    MOVABLE,
    Limits,
    held_values,
    joint_limits,
    kinematic_joints,
    planning_joints,
)
from trajcache.geometry.model.pairs import skipped_pairs
from trajcache.geometry.model.robot import BaseType, CollisionElement, RobotModel
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.model.srdf import Srdf, parse_srdf

BASE_VELOCITY = (0.5, 0.5, 1.0)
_JOINT_TYPES = (*MOVABLE, "fixed", "floating", "planar")
_GEOMETRY_ATTRS = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length")}


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


def _elements(robot: Any, links: list[str], resolver: MeshResolver) -> list[CollisionElement]:
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
    base_type = _base_type(base)
    robot = _parse(urdf)
    links, ordered = _topology(robot)
    semantic = parse_srdf(srdf) if srdf is not None else None
    warnings: list[str] = []
    planning = planning_joints(list(robot.joints), joint_names, group, semantic, warnings)
    limits = {j.name: joint_limits(j) for j in ordered if j.type in MOVABLE}
    if unbounded := [n for n in planning if limits[n] is None]:
        raise RobotModelError(
            f"prismatic joints {unbounded} have no <limit>; they cannot be planned"
        )
    held = held_values(ordered, planning, limits, joint_values, semantic)
    planar = base_type is BaseType.PLANAR
    joints = kinematic_joints(ordered, links, planning, 3 if planar else 0, held, limits)
    resolver = MeshResolver(files or {})
    elements = _elements(robot, links, resolver)
    table = _limit_table(planning, limits, planar=planar)
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
    return _with_pairs_and_states(model, semantic, warnings)


def _base_type(base: BaseType | str) -> BaseType:
    try:
        return BaseType(base)
    except ValueError as exc:
        raise RobotModelError(f"unknown base type {base!r}; expected 'fixed' or 'planar'") from exc


def _limit_table(planning: list[str], limits: Limits, *, planar: bool) -> FloatArray:
    """(lower, upper, velocity) rows of the planning dofs: the base's first when it is planar."""
    base_limits = [(-math.inf, math.inf, v) for v in BASE_VELOCITY[:2]]
    base_limits.append((-math.pi, math.pi, BASE_VELOCITY[2]))
    planned = [limits[n] for n in planning]
    return np.array((base_limits if planar else []) + planned, dtype=float).reshape(-1, 3)


def _with_pairs_and_states(
    model: RobotModel, semantic: Srdf | None, warnings: list[str]
) -> RobotModel:
    """`model` with its unchecked pairs, the SRDF's named states and what was not applied."""
    reasons = skipped_pairs(model, semantic)
    named = named_states(model, semantic) if semantic is not None else {}
    if semantic is not None:
        known = set(model.link_names)
        unknown = sorted({n for a, b, _ in semantic.disabled for n in (a, b) if n not in known})
        if unknown:
            warnings.append(f"SRDF disable_collisions name unknown links {unknown}; not applied")
    return replace(
        model,
        pair_reasons=reasons,
        named_states=named,
        warnings=tuple(warnings),
    )


def named_states(model: RobotModel, srdf: Srdf) -> dict[str, tuple[float, ...]]:
    """The SRDF group_states that give every planning joint a value: those values, in
    `joint_names` order (values of other joints are left out; held joints keep theirs)."""
    out: dict[str, tuple[float, ...]] = {}
    for state in srdf.states:
        if all(name in state.values for name in model.joint_names):
            out.setdefault(state.name, tuple(state.values[n] for n in model.joint_names))
    return out
