"""The reference robot: an xArm7-like 7-DOF arm on a planar mobile base (see REFERENCE.md).

The arm's joint origins and limits follow the xArm7 kinematics exactly; link geometry is
approximated by cylinders and spheres sized from the real links' bounding boxes. The base is a
0.60 × 0.50 × 0.40 m box whose frame sits on the floor at the centre of its footprint; the arm is
mounted on top, 0.15 m forward of the centre. The tool is a 0.15 m spray nozzle; the fixed
`tool_tip` frame marks its end.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from trajcache.geometry.model.robot import RobotModel

REFERENCE_BASE = "planar"
REFERENCE_NAME = "xarm7-mobile"
ARM_MOUNT_XYZ = (0.15, 0.0, 0.40)
BASE_SIZE = (0.60, 0.50, 0.40)
TOOL_LENGTH = 0.15
ARM_JOINT_NAMES = tuple(f"joint{i}" for i in range(1, 8))
VELOCITY_LIMIT = 3.14
# A compact stowed arm (tool pointing down over the base, inside the footprint); verified free of
# self-collision and of collision with the restroom scene at every station (tests).
STOWED_ARM = (0.0, -1.3, 0.0, 0.8, 0.0, 2.1, 0.0)
_HALF_PI = math.pi / 2
_TWO_PI = 6.283185307


@dataclass(frozen=True)
class _Joint:
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    lower: float
    upper: float


# REFERENCE.md joint table (parent link → child link origin, revolute about local z).
ARM_JOINTS: tuple[_Joint, ...] = (
    _Joint((0.0, 0.0, 0.267), (0.0, 0.0, 0.0), -_TWO_PI, _TWO_PI),
    _Joint((0.0, 0.0, 0.0), (-_HALF_PI, 0.0, 0.0), -2.059, 2.0944),
    _Joint((0.0, -0.293, 0.0), (_HALF_PI, 0.0, 0.0), -_TWO_PI, _TWO_PI),
    _Joint((0.0525, 0.0, 0.0), (_HALF_PI, 0.0, 0.0), -0.19198, 3.927),
    _Joint((0.0775, -0.3425, 0.0), (_HALF_PI, 0.0, 0.0), -_TWO_PI, _TWO_PI),
    _Joint((0.0, 0.0, 0.0), (_HALF_PI, 0.0, 0.0), -1.69297, math.pi),
    _Joint((0.076, 0.097, 0.0), (-_HALF_PI, 0.0, 0.0), -_TWO_PI, _TWO_PI),
)


@dataclass(frozen=True)
class LinkGeometry:
    """One collision primitive in a link frame; sizes as in `Shape` (cylinders along `axis`)."""

    kind: str  # "box" | "sphere" | "cylinder"
    size: tuple[float, ...]
    xyz: tuple[float, float, float]
    axis: str = "z"


def _cyl(radius: float, length: float, xyz: tuple[float, float, float], axis: str) -> LinkGeometry:
    return LinkGeometry("cylinder", (radius, length), xyz, axis)


LINK_GEOMETRY: dict[str, tuple[LinkGeometry, ...]] = {
    "base_link": (LinkGeometry("box", BASE_SIZE, (0.0, 0.0, BASE_SIZE[2] / 2)),),
    "link_base": (_cyl(0.06, 0.155, (0.0, 0.0, 0.0775), "z"),),
    # link1 [-.049..048, -.057..075, -.112..048]: column down to link_base + joint2 housing
    "link1": (_cyl(0.048, 0.112, (0.0, 0.0, -0.056), "z"), _cyl(0.048, 0.132, (0, 0.009, 0), "y")),
    # link2 [-.048..047, -.192..047, -.042..119]: joint2 housing + upper arm along -y
    "link2": (_cyl(0.047, 0.161, (0, 0, 0.0385), "z"), _cyl(0.045, 0.192, (0, -0.096, 0), "y")),
    # link3 [-.042..095, -.067..069, -.101..043]: column + joint4 housing at x = 0.0525
    "link3": (
        _cyl(0.042, 0.101, (0, 0, -0.0505), "z"),
        _cyl(0.043, 0.136, (0.0525, 0.001, 0), "y"),
    ),
    # link4 [-.043..120, -.169..043, -.043..107]: elbow housing + forearm along -y at x = 0.0775
    "link4": (
        _cyl(0.043, 0.15, (0, 0, 0.032), "z"),
        _cyl(0.0425, 0.169, (0.0775, -0.0845, 0), "y"),
    ),
    # link5 [-.042..042, -.043..086, -.173..038]: forearm + joint6 housing
    "link5": (_cyl(0.042, 0.173, (0, 0, -0.0865), "z"), _cyl(0.042, 0.129, (0, 0.0215, 0), "y")),
    # link6 [-.038..114, -.038..069, -.038..058]: joint6 housing + wrist toward the flange
    "link6": (_cyl(0.038, 0.096, (0, 0, 0.010), "z"), _cyl(0.038, 0.107, (0.076, 0.0155, 0), "y")),
    # link7 [-.037..037, -.052..037, -.028..0]: the flange
    "link7": (_cyl(0.040, 0.028, (0.0, -0.005, -0.014), "z"),),
    # spray nozzle along the flange normal: mount, pipe, tip
    "tool": (
        _cyl(0.030, 0.030, (0.0, 0.0, 0.015), "z"),
        _cyl(0.015, TOOL_LENGTH - 0.03, (0.0, 0.0, 0.015 + TOOL_LENGTH / 2), "z"),
        LinkGeometry("sphere", (0.020,), (0.0, 0.0, TOOL_LENGTH)),
    ),
}

_AXIS_RPY = {"x": (0.0, _HALF_PI, 0.0), "y": (_HALF_PI, 0.0, 0.0), "z": (0.0, 0.0, 0.0)}


def _fmt(values: tuple[float, ...]) -> str:
    return " ".join(repr(float(v)) for v in values)


def _collision_xml(g: LinkGeometry) -> str:
    if g.kind == "cylinder":
        geometry = f'<cylinder radius="{g.size[0]}" length="{g.size[1]}"/>'
    elif g.kind == "sphere":
        geometry = f'<sphere radius="{g.size[0]}"/>'
    else:
        geometry = f'<box size="{_fmt(g.size)}"/>'
    rpy = _AXIS_RPY[g.axis] if g.kind == "cylinder" else (0.0, 0.0, 0.0)
    origin = f'<origin xyz="{_fmt(g.xyz)}" rpy="{_fmt(rpy)}"/>'
    return f"    <collision>{origin}<geometry>{geometry}</geometry></collision>"


def _link_xml(name: str) -> str:
    body = "\n".join(_collision_xml(e) for e in LINK_GEOMETRY.get(name, ()))
    return f'  <link name="{name}">\n{body}\n  </link>' if body else f'  <link name="{name}"/>'


def _joint_xml(
    name: str, kind: str, parent: str, child: str, xyz: tuple[float, ...], rpy: tuple[float, ...]
) -> list[str]:
    return [
        f'  <joint name="{name}" type="{kind}">',
        f'    <parent link="{parent}"/>',
        f'    <child link="{child}"/>',
        f'    <origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>',
    ]


@functools.lru_cache(maxsize=1)
def reference_urdf() -> str:
    """URDF text of the reference robot (arm joints `joint1` … `joint7`)."""
    links = ["base_link", "link_base", *(f"link{i}" for i in range(1, 8)), "tool", "tool_tip"]
    lines = ['<?xml version="1.0"?>', f'<robot name="{REFERENCE_NAME}">']
    lines += [_link_xml(name) for name in links]
    lines += _joint_xml("arm_mount", "fixed", "base_link", "link_base", ARM_MOUNT_XYZ, (0, 0, 0))
    lines.append("  </joint>")
    parent = "link_base"
    for name, joint in zip(ARM_JOINT_NAMES, ARM_JOINTS, strict=True):
        child = f"link{name[-1]}"
        lines += _joint_xml(name, "revolute", parent, child, joint.xyz, joint.rpy)
        lines += [
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{joint.lower}" upper="{joint.upper}" effort="50"'
            f' velocity="{VELOCITY_LIMIT}"/>',
            "  </joint>",
        ]
        parent = child
    lines += _joint_xml("tool_mount", "fixed", "link7", "tool", (0, 0, 0), (0, 0, 0))
    lines.append("  </joint>")
    lines += _joint_xml(
        "tool_tip_joint", "fixed", "tool", "tool_tip", (0, 0, TOOL_LENGTH), (0,) * 3
    )
    lines += ["  </joint>", "</robot>", ""]
    return "\n".join(lines)


@functools.lru_cache(maxsize=1)
def reference_model() -> RobotModel:
    """The reference robot loaded as a planar-base RobotModel (cached)."""
    from trajcache.geometry.model.urdf import load_robot_model

    return load_robot_model(reference_urdf(), base=REFERENCE_BASE, name=REFERENCE_NAME)
