"""The robots of the test suite: URDF builders, named robots, and the URDF files in data/urdf.

Every test that needs a robot description takes it from here. A URDF whose malformation is the
point of its test stays a literal next to that test.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path

Vector = tuple[float, float, float]

URDF_DIR = Path(__file__).parent / "data" / "urdf"
Z_AXIS: Vector = (0, 0, 1)
Y_AXIS: Vector = (0, 1, 0)
ALONG_X: Vector = (0, math.pi / 2, 0)  # turns a cylinder's z axis onto x

# Sent where a URDF is only carried, never parsed (fake transports, fake planners, stored rows).
OPAQUE_URDF = "<robot/>"
# The smallest URDF that parses: one link, nothing to move.
ONE_LINK_URDF = '<robot name="s"><link name="l"/></robot>'


# --- XML pieces -------------------------------------------------------------------------------


def _vector(values: Sequence[float]) -> str:
    return " ".join(str(v) for v in values)


def _origin(xyz: Sequence[float] | None, rpy: Sequence[float] | None) -> str:
    if xyz is None and rpy is None:
        return ""
    rpy_text = "" if rpy is None else f' rpy="{_vector(rpy)}"'
    return f'<origin xyz="{_vector(xyz or (0, 0, 0))}"{rpy_text}/>'


def box(x: float, y: float, z: float) -> str:
    """A box geometry."""
    return f'<box size="{_vector((x, y, z))}"/>'


def cylinder(radius: float, length: float) -> str:
    """A cylinder geometry (along its z axis)."""
    return f'<cylinder radius="{radius}" length="{length}"/>'


def sphere(radius: float) -> str:
    """A sphere geometry."""
    return f'<sphere radius="{radius}"/>'


def mesh(filename: str, *, scale: str | None = None) -> str:
    """A mesh geometry referring to a file of the robot's archive."""
    scale_text = "" if scale is None else f' scale="{scale}"'
    return f'<mesh filename="{filename}"{scale_text}/>'


def collision(
    geometry: str, *, xyz: Sequence[float] | None = None, rpy: Sequence[float] | None = None
) -> str:
    """A collision element of a link."""
    return f"<collision>{_origin(xyz, rpy)}<geometry>{geometry}</geometry></collision>"


def link(name: str, *collisions: str) -> str:
    """A link with its collision elements (none: a link without geometry)."""
    if not collisions:
        return f'<link name="{name}"/>'
    return f'<link name="{name}">{"".join(collisions)}</link>'


def joint(
    name: str,
    kind: str,
    parent: str,
    child: str,
    *,
    xyz: Sequence[float] | None = None,
    rpy: Sequence[float] | None = None,
    axis: Sequence[float] | None = None,
    limit: tuple[float, float] | None = None,
    velocity: float = 1,
) -> str:
    """A joint; `limit` is (lower, upper), None for no <limit> element."""
    parts = [f'<parent link="{parent}"/><child link="{child}"/>', _origin(xyz, rpy)]
    if axis is not None:
        parts.append(f'<axis xyz="{_vector(axis)}"/>')
    if limit is not None:
        lower, upper = limit
        parts.append(f'<limit lower="{lower}" upper="{upper}" effort="1" velocity="{velocity}"/>')
    return f'<joint name="{name}" type="{kind}">{"".join(parts)}</joint>'


def robot(name: str, *parts: str) -> str:
    """A URDF document of links and joints (joints keep their order: it is the planning order)."""
    body = "".join(f"\n  {part}" for part in parts)
    return f'<?xml version="1.0"?>\n<robot name="{name}">{body}\n</robot>\n'


def with_mimic(urdf: str, *, follower: str, leader: str, multiplier: float, offset: float) -> str:
    """`urdf` with joint `follower` mimicking joint `leader`."""
    pattern = re.compile(rf'(<joint name="{re.escape(follower)}".*?)(\s*</joint>)', re.DOTALL)
    mimic = f'<mimic joint="{leader}" multiplier="{multiplier}" offset="{offset}"/>'
    edited, count = pattern.subn(rf"\g<1>{mimic}\g<2>", urdf, count=1)
    if count != 1:
        raise ValueError(f"no joint {follower!r} in the URDF")
    return edited


def urdf_file(name: str) -> Path:
    """The path of `data/urdf/<name>.urdf`."""
    return URDF_DIR / f"{name}.urdf"


# --- families ---------------------------------------------------------------------------------


def planar_arm(
    lengths: Sequence[float],
    *,
    name: str = "arm",
    links: Sequence[str] | None = None,
    joints: Sequence[str] | None = None,
    limits: float | Sequence[float] = 3,
    height: float = 0,
    radius: float = 0.01,
    width: float | None = None,
    extra: Sequence[str] = (),
) -> str:
    """A serial arm in a horizontal plane `height` above its root link "root": link i is a rod
    of `lengths[i]` along x (a cylinder of `radius`, or a square box of `width`) turning about z
    within ±limit; links l1… and joints j1… unless named. `extra` parts are appended."""
    count = len(lengths)
    link_names = list(links or [f"l{i + 1}" for i in range(count)])
    joint_names = list(joints or [f"j{i + 1}" for i in range(count)])
    bounds = [limits] * count if isinstance(limits, float | int) else list(limits)
    parts = [link("root")]
    for length, link_name in zip(lengths, link_names, strict=True):
        if width is None:
            shape = collision(cylinder(radius, length), xyz=(length / 2, 0, 0), rpy=ALONG_X)
        else:
            shape = collision(box(length, width, width), xyz=(length / 2, 0, 0))
        parts.append(link(link_name, shape))
    parents = ["root", *link_names]
    offsets = [(0, 0, height), *((length, 0, 0) for length in lengths)]
    for i, joint_name in enumerate(joint_names):
        bound = bounds[i]
        parts.append(
            joint(joint_name, "revolute", parents[i], link_names[i], xyz=offsets[i],
                  axis=Z_AXIS, limit=(-bound, bound))
        )  # fmt: skip
    return robot(name, *parts, *extra)


def two_joint_arm(
    *, name: str = "two_joint", elbow_limit: float = 1.5, finger: bool = False
) -> str:
    """An upright arm on a base box, shoulder and elbow about y; optionally a prismatic finger.
    Its link geometry keeps the allowed-pair sampling quick."""
    parts = [
        link("base", collision(box(0.2, 0.2, 0.1), xyz=(0, 0, 0.05))),
        link("upper", collision(cylinder(0.03, 0.3), xyz=(0, 0, 0.15))),
        link("fore", collision(cylinder(0.02, 0.2), xyz=(0, 0, 0.1))),
    ]
    if finger:
        parts.append(link("finger", collision(box(0.01, 0.01, 0.04), xyz=(0, 0, 0.02))))
    parts += [
        joint("shoulder", "revolute", "base", "upper", xyz=(0, 0, 0.1), axis=Y_AXIS,
              limit=(-2.0, 2.0)),
        joint("elbow", "revolute", "upper", "fore", xyz=(0, 0, 0.3), axis=Y_AXIS,
              limit=(-elbow_limit, elbow_limit)),
    ]  # fmt: skip
    if finger:
        parts.append(
            joint("finger", "prismatic", "fore", "finger", xyz=(0, 0, 0.2), axis=(1, 0, 0),
                  limit=(0, 0.04), velocity=0.1)
        )  # fmt: skip
    return robot(name, *parts)


def upright_chain(n_links: int, *, bare: Sequence[int] = ()) -> str:
    """A chain of 0.2 m cylinders l0… stacked along z, joints about y with alternating roll;
    the links numbered in `bare` have no geometry."""
    rod = collision(cylinder(0.03, 0.2), xyz=(0, 0, 0.1))
    links = [link(f"l{i}") if i in bare else link(f"l{i}", rod) for i in range(n_links)]
    joints = [
        joint(f"j{i}", "revolute", f"l{i - 1}", f"l{i}", xyz=(0, 0, 0.2),
              rpy=(0.5 * (i % 2), 0, 0), axis=Y_AXIS, limit=(-2.5, 2.5))
        for i in range(1, n_links)
    ]  # fmt: skip
    return robot("chain", *links, *joints)


def mesh_robot(*filenames: str, scale: str = "1 1 1") -> str:
    """Links l0… each holding one mesh, all fixed to l0."""
    links = [link(f"l{i}", collision(mesh(f, scale=scale))) for i, f in enumerate(filenames)]
    joints = [joint(f"j{i}", "fixed", "l0", f"l{i}") for i in range(1, len(filenames))]
    return robot("meshy", *links, *joints)


# --- named robots -----------------------------------------------------------------------------

TWO_JOINT_URDF = two_joint_arm()
PINCER_URDF = two_joint_arm(name="pincer", finger=True)
PINCER_SRDF = """<?xml version="1.0"?>
<robot name="pincer">
  <group name="arm"><joint name="shoulder"/><joint name="elbow"/></group>
  <group name="hand"><joint name="finger"/></group>
  <group_state name="ready" group="arm">
    <joint name="shoulder" value="0.5"/><joint name="elbow" value="-0.4"/>
  </group_state>
  <group_state name="open" group="hand"><joint name="finger" value="0.03"/></group_state>
  <disable_collisions link1="base" link2="fore" reason="Never"/>
</robot>
"""

# One revolute joint about z carrying a 1 m rod (radius 1 cm) along x, 0.5 m above the floor.
ROD_URDF = planar_arm((1.0,), name="rod", links=("rod",), joints=("j",), height=0.5)
# A fixed-base two-link planar arm (rods of 0.5 m and 0.4 m), 0.5 m above the floor.
TWO_ROD_URDF = planar_arm(
    (0.5, 0.4), name="two_link", links=("upper", "fore"), joints=("shoulder", "elbow"),
    limits=(3, 2.8), height=0.5, radius=0.02,
)  # fmt: skip
# A planar two-link arm of boxes on the floor, short of its joints.
BOXED_TWO_LINK_URDF = robot(
    "two_link",
    link("base"),
    link("upper", collision(box(0.26, 0.04, 0.04), xyz=(0.15, 0, 0))),
    link("fore", collision(box(0.16, 0.04, 0.04), xyz=(0.12, 0, 0))),
    joint("shoulder", "revolute", "base", "upper", axis=Z_AXIS, limit=(-3, 3)),
    joint("elbow", "revolute", "upper", "fore", xyz=(0.3, 0, 0), axis=Z_AXIS, limit=(-2.5, 2.5)),
)
# A lift whose moving link is a mesh from the archive (meshes/part.stl of package "meshy").
MESH_URDF = robot(
    "meshy",
    link("base", collision(box(0.3, 0.3, 0.1))),
    link("arm", collision(mesh("package://meshy/meshes/part.stl"), xyz=(0, 0, 0.3))),
    joint("lift", "prismatic", "base", "arm", axis=Z_AXIS, limit=(0, 0.5), velocity=0.2),
)
# A 0.4 × 0.3 × 0.2 m box turning about z at the origin.
BLOCK_URDF = robot(
    "block",
    link("root"),
    link("block", collision(box(0.4, 0.3, 0.2))),
    joint("j", "revolute", "root", "block", axis=Z_AXIS, limit=(-3, 3)),
)
# A ball of 10 cm radius turning about z, 0.5 m out and 0.3 m up.
OFFSET_BALL_URDF = robot(
    "p",
    link("base"),
    link("arm", collision(sphere(0.1))),
    joint("j", "revolute", "base", "arm", xyz=(0.5, 0, 0.3), axis=Z_AXIS, limit=(-2, 2)),
)
# A ball of 2 cm radius sliding along x.
SLIDING_BALL_URDF = robot(
    "ball",
    link("root"),
    link("ball", collision(sphere(0.02))),
    joint("x", "prismatic", "root", "ball", axis=(1, 0, 0), limit=(-3, 3)),
)
# A turn about z, then a slide along x 0.3 m out, carrying a ball of 10 cm radius.
TURN_AND_SLIDE_URDF = robot(
    "t",
    link("base"),
    link("a"),
    link("b", collision(sphere(0.1))),
    joint("turn", "revolute", "base", "a", axis=Z_AXIS, limit=(-3, 3)),
    joint("slide", "prismatic", "a", "b", xyz=(0.3, 0, 0), axis=(1, 0, 0), limit=(0, 0.5)),
)
# One revolute joint and no geometry at all.
BARE_JOINT_URDF = robot(
    "ghost",
    link("a"),
    link("b"),
    joint("j", "revolute", "a", "b", axis=Z_AXIS, limit=(-3, 3)),
)
# A revolute and a prismatic joint, neither with a <limit>.
UNLIMITED_URDF = robot(
    "r",
    link("a"),
    link("b"),
    link("c"),
    joint("x", "revolute", "a", "b"),
    joint("y", "prismatic", "b", "c"),
)
# A fixed-base arm with a fixed joint, a prismatic joint and a side branch (a camera link).
BRANCHED_URDF = robot(
    "branched",
    link("base"),
    link("mount"),
    link("slider", collision(box(0.1, 0.1, 0.1))),
    link("arm", collision(box(0.5, 0.05, 0.05), xyz=(0.25, 0, 0))),
    link("camera"),
    link("tip"),
    joint("fix", "fixed", "base", "mount", xyz=(0, 0, 0.3), rpy=(0, 0, 0.4)),
    joint("lift", "prismatic", "mount", "slider", axis=Z_AXIS, limit=(0, 0.5), velocity=0.2),
    joint("turn", "revolute", "slider", "arm", xyz=(0, 0, 0.1), rpy=(0.3, 0, 0), axis=Z_AXIS,
          limit=(-3, 3)),
    joint("cam", "fixed", "slider", "camera", xyz=(0.1, 0, 0)),
    joint("tool", "fixed", "arm", "tip", xyz=(0.5, 0, 0), rpy=(0, 0.2, 0)),
)  # fmt: skip

# Files, for the robots too rich to build here (and for tools that read a path).
# arm: rpy offsets, fixed joints, a branch, a skew continuous joint, a prismatic joint, ±2π
# limits, a link without geometry, joints out of topological order.
ARM_PATH = urdf_file("arm")
ARM_URDF = ARM_PATH.read_text()
# swing: "fore" can fold back onto "base_link"; "mast" is rigid and far; "upper" always overlaps.
SWING_URDF = urdf_file("swing").read_text()
