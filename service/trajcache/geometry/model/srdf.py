"""SRDF: the robot team's planning groups, named states and disabled collision pairs.

Read as MoveIt reads it (`srdfdom`): a group lists joints, links (their parent joints), chains
(the joints from `base_link` down to `tip_link`) and other groups; its planning joints are the
movable ones among them; as in `srdfdom`, a member the URDF does not have is skipped with a
warning. A `group_state` gives joint values by name. `disable_collisions` names two links whose
contact is allowed; entries naming links the URDF does not have are not applied. Virtual joints,
passive joints and end effectors are read by MoveIt for other purposes and are ignored here.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import defusedxml.ElementTree as DefusedET
from defusedxml import DefusedXmlException

from trajcache.geometry.errors import RobotModelError

MAX_GROUP_DEPTH = 16


@dataclass(frozen=True)
class Group:
    """One `<group>` as written: its joints, links, chains and subgroups."""

    name: str
    joints: tuple[str, ...] = ()
    links: tuple[str, ...] = ()
    chains: tuple[tuple[str, str], ...] = ()  # (base_link, tip_link)
    subgroups: tuple[str, ...] = ()


@dataclass(frozen=True)
class GroupState:
    """One `<group_state>`: joint values by name."""

    name: str
    group: str
    values: Mapping[str, float]


@dataclass(frozen=True)
class Srdf:
    """The parts of an SRDF the service uses."""

    name: str
    groups: Mapping[str, Group] = field(default_factory=dict)
    states: tuple[GroupState, ...] = ()
    disabled: tuple[tuple[str, str, str], ...] = ()  # (link1, link2, reason)
    end_effectors: Mapping[str, str] = field(default_factory=dict)  # name → parent link

    def state(self, name: str) -> GroupState:
        """The group state `name`; RobotModelError listing the known ones when there is none."""
        for state in self.states:
            if state.name == name:
                return state
        known = sorted({s.name for s in self.states})
        raise RobotModelError(f"the SRDF has no group_state {name!r}; it has {known}")


def parse_srdf(text: str) -> Srdf:
    """Parse SRDF text (DTDs and entities refused); RobotModelError names what is wrong."""
    try:
        root = DefusedET.fromstring(text.strip(), forbid_dtd=True)
    except DefusedXmlException as exc:
        raise RobotModelError(
            f"SRDF must not contain DOCTYPE or ENTITY declarations ({exc!r})"
        ) from exc
    except ET.ParseError as exc:
        raise RobotModelError(f"malformed SRDF XML: {exc}") from exc
    if root.tag != "robot":
        raise RobotModelError(f"SRDF root element is <{root.tag}>, expected <robot>")
    groups: dict[str, Group] = {}
    for element in root.findall("group"):
        group = _group(element)
        if group.name in groups:
            raise RobotModelError(f"SRDF defines group {group.name!r} twice")
        groups[group.name] = group
    states = tuple(_state(element) for element in root.findall("group_state"))
    disabled = []
    for element in root.findall("disable_collisions"):
        link1, link2 = element.get("link1"), element.get("link2")
        if not link1 or not link2:
            raise RobotModelError("an SRDF <disable_collisions> lacks link1 or link2")
        disabled.append((link1, link2, element.get("reason") or ""))
    effectors = {
        _named(e, "end_effector"): e.get("parent_link") or "" for e in root.findall("end_effector")
    }
    return Srdf(root.get("name") or "", groups, states, tuple(disabled), effectors)


def _named(element: ET.Element, what: str) -> str:
    name = element.get("name")
    if not name:
        raise RobotModelError(f"an SRDF <{what}> has no name attribute")
    return name


def _group(element: ET.Element) -> Group:
    name = _named(element, "group")
    chains = []
    for chain in element.findall("chain"):
        base, tip = chain.get("base_link"), chain.get("tip_link")
        if not base or not tip:
            raise RobotModelError(f"SRDF group {name!r}: a <chain> lacks base_link or tip_link")
        chains.append((base, tip))
    return Group(
        name=name,
        joints=tuple(_named(e, "joint") for e in element.findall("joint")),
        links=tuple(_named(e, "link") for e in element.findall("link")),
        chains=tuple(chains),
        subgroups=tuple(_named(e, "group") for e in element.findall("group")),
    )


def _state(element: ET.Element) -> GroupState:
    name = _named(element, "group_state")
    values: dict[str, float] = {}
    for joint in element.findall("joint"):
        jname = _named(joint, "joint")
        raw = (joint.get("value") or "").split()
        if len(raw) != 1:
            raise RobotModelError(
                f"SRDF group_state {name!r}: joint {jname!r} needs one value, got {raw}"
            )
        try:
            value = float(raw[0])
        except ValueError:
            raise RobotModelError(
                f"SRDF group_state {name!r}: joint {jname!r} value {raw[0]!r} is not a number"
            ) from None
        if not math.isfinite(value):
            raise RobotModelError(f"SRDF group_state {name!r}: joint {jname!r} is not finite")
        values[jname] = value
    return GroupState(name, element.get("group") or "", values)


def group_joints(
    srdf: Srdf, name: str, *, parent_of: Mapping[str, tuple[str, str]], joints: Sequence[str]
) -> tuple[set[str], list[str]]:
    """Every joint of group `name`, its subgroups included (movable or not), and warnings about
    the members the URDF does not have (skipped).

    `parent_of[link]` is (joint, parent link) of the joint whose child is `link`; `joints` are
    the URDF's joint names.
    """
    if name not in srdf.groups:
        raise RobotModelError(f"the SRDF has no group {name!r}; it has {sorted(srdf.groups)}")
    links = set(parent_of) | {parent for _, parent in parent_of.values()}
    out: set[str] = set()
    warnings: list[str] = []
    _collect(srdf, name, out, (set(joints), links, parent_of, warnings), ())
    return out, warnings


# joints, links, parent_of, warnings
_Tree = tuple[set[str], set[str], Mapping[str, tuple[str, str]], list[str]]


def _collect(srdf: Srdf, name: str, out: set[str], tree: _Tree, path: tuple[str, ...]) -> None:
    joints, links, parent_of, warnings = tree
    if name in path or len(path) > MAX_GROUP_DEPTH:
        raise RobotModelError(f"SRDF groups include each other in a cycle: {[*path, name]}")
    if name not in srdf.groups:
        raise RobotModelError(f"SRDF group {path[-1]!r} includes unknown group {name!r}")
    group = srdf.groups[name]
    for joint in group.joints:
        if joint not in joints:
            warnings.append(f"SRDF group {name!r}: unknown joint {joint!r} skipped")
            continue
        out.add(joint)
    for link in group.links:
        if link not in links:
            warnings.append(f"SRDF group {name!r}: unknown link {link!r} skipped")
        elif link in parent_of:
            out.add(parent_of[link][0])
    for base, tip in group.chains:
        if base not in links or tip not in links:
            warnings.append(f"SRDF group {name!r}: chain {base!r} → {tip!r} has an unknown link")
            continue
        out.update(_chain(name, base, tip, parent_of))
    for sub in group.subgroups:
        _collect(srdf, sub, out, tree, (*path, name))


def _chain(group: str, base: str, tip: str, parent_of: Mapping[str, tuple[str, str]]) -> list[str]:
    """Joints from `base` down to `tip`."""
    joints: list[str] = []
    link = tip
    while link != base:
        if link not in parent_of:
            raise RobotModelError(
                f"SRDF group {group!r}: chain tip {tip!r} is not below base {base!r}"
            )
        joint, link = parent_of[link]
        joints.append(joint)
    return joints
