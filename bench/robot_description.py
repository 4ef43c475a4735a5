"""Which robot the dense check builds: URDF and SRDF files, base type, planning and held joints.

Read from the files as `example-robot-data` ships them, without the service: an SRDF group's
joints (its joints, chains and subgroups) and the URDF's mimic relations.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from trajcache.reference.example_robots import ExampleRobot, robots_dir

MOVABLE = frozenset({"revolute", "continuous", "prismatic"})


@dataclass(frozen=True)
class RobotDescription:
    """What the check needs to know about a robot: files, base type, planning and held joints."""

    urdf_path: Path
    package_dir: Path  # the folder that `package://<name>/…` URIs resolve in
    joint_names: tuple[str, ...]  # planning joints, in state order
    srdf_path: Path | None = None  # None: every non-adjacent pair is checked
    base: str = "fixed"  # or "planar"
    held: Mapping[str, float] = field(default_factory=dict)


def _link(joint: ET.Element, role: str) -> str:
    element = joint.find(role)
    return "" if element is None else str(element.get("link"))


def srdf_group_joints(srdf: str, group: str, urdf: str) -> set[str]:
    """Joints of an SRDF planning group: its joints, chains and subgroups (fixed ones included)."""
    groups = {g.get("name"): g for g in ET.fromstring(srdf).findall("group")}
    parent_joint = {  # child link → (joint, parent link)
        _link(j, "child"): (str(j.get("name")), _link(j, "parent"))
        for j in ET.fromstring(urdf).findall("joint")
    }
    out: set[str] = set()
    todo = [group]
    while todo:
        node = groups[todo.pop()]
        out.update(str(j.get("name")) for j in node.iter("joint"))
        for chain in node.iter("chain"):  # a chain whose base is not above its tip is skipped
            link, joints = chain.get("tip_link"), []
            while link != chain.get("base_link") and link in parent_joint:
                joint, link = parent_joint[link]
                joints.append(joint)
            if link == chain.get("base_link"):
                out.update(joints)
        todo.extend(str(g.get("name")) for g in node if g.tag == "group")
    return out


def describe(
    example: ExampleRobot,
    *,
    joint_names: Sequence[str] | None = None,
    held: Mapping[str, float] | None = None,
    srdf: bool = True,
) -> RobotDescription:
    """The description of an example robot; planning joints default to its SRDF group, its
    listed joints, or every movable joint in URDF order."""
    root = robots_dir()
    urdf = example.urdf
    if joint_names is None:
        joint_names = example.joint_names
    if joint_names is None:
        wanted = (
            srdf_group_joints(example.srdf or "", example.group, urdf) if example.group else None
        )
        joint_names = [
            str(j.get("name"))
            for j in ET.fromstring(urdf).findall("joint")
            if j.get("type") in MOVABLE
            and j.find("mimic") is None
            and (wanted is None or j.get("name") in wanted)
        ]
    return RobotDescription(
        urdf_path=root / example.urdf_path,
        package_dir=root.parent.parent,
        joint_names=tuple(joint_names),
        srdf_path=root / example.srdf_path if srdf and example.srdf_path else None,
        base=example.base,
        held={**example.joint_values, **(held or {})},
    )


def urdf_mimics(urdf: str) -> dict[str, tuple[str, float, float]]:
    """follower joint → (leader joint, multiplier, offset)."""
    out = {}
    for joint in ET.fromstring(urdf).findall("joint"):
        mimic = joint.find("mimic")
        if mimic is not None:
            multiplier = float(mimic.get("multiplier", 1.0))
            out[str(joint.get("name"))] = (
                str(mimic.get("joint")),
                multiplier,
                float(mimic.get("offset", 0.0)),
            )
    return out
