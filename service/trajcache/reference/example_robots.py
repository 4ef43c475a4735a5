"""Real robot descriptions as the `example-robot-data` package (PyPI) ships them.

Each entry names a URDF, its SRDF where the package has one, and how it is registered: the SRDF
group to plan with, or the listed planning joints and base type for a robot without one. The
mesh files come with it, keyed as `robots/<path below the package's robots/ folder>`, which is
what the URDFs' `package://example-robot-data/robots/...` URIs resolve to in an upload.

An archive for the service holds each mesh at the path its URI names below the package
(`package://example-robot-data/robots/panda_description/meshes/…` at
`robots/panda_description/meshes/…`): `archive()` writes it so, and `trajcache robots fetch`
writes it to disk. The package is an optional extra (`pip install trajcache[robots]`, and in
`dev`); `robots_dir` raises LookupError without it.
"""

from __future__ import annotations

import io
import re
import sysconfig
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

_MESH_URI = re.compile(r'filename="package://example-robot-data/robots/([^"]+)"')


@dataclass(frozen=True)
class ExampleRobot:
    """How one robot of the package is registered."""

    name: str
    urdf_path: str  # below robots/
    srdf_path: str | None = None
    group: str | None = None  # SRDF planning group
    joint_names: tuple[str, ...] | None = None  # planning joints, for robots without an SRDF
    base: str = "fixed"
    joint_values: dict[str, float] = field(default_factory=dict)  # held joints

    @property
    def urdf(self) -> str:
        """The URDF text as shipped."""
        return (robots_dir() / self.urdf_path).read_text(encoding="utf-8")

    @property
    def srdf(self) -> str | None:
        """The SRDF text as shipped, or None."""
        if self.srdf_path is None:
            return None
        return (robots_dir() / self.srdf_path).read_text(encoding="utf-8")

    def files(self) -> dict[str, bytes]:
        """The mesh files the URDF references, keyed as `robots/<path>`."""
        root = robots_dir()
        paths = sorted(set(_MESH_URI.findall(self.urdf)))
        return {f"robots/{p}": (root / p).read_bytes() for p in paths if (root / p).is_file()}

    def archive(self) -> bytes:
        """A zip of `files()`, laid out as the URDF's mesh URIs resolve in an upload."""
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
            for path, data in self.files().items():
                archive.writestr(path, data)
        return buffer.getvalue()


ROBOTS: dict[str, ExampleRobot] = {
    robot.name: robot
    for robot in (
        ExampleRobot(
            "panda", "panda_description/urdf/panda.urdf", "panda_description/srdf/panda.srdf", "arm"
        ),
        ExampleRobot(
            "ur5",
            "ur_description/urdf/ur5_robot.urdf",
            "ur_description/srdf/ur5.srdf",  # collision matrix only, no groups
        ),
        ExampleRobot(
            "xarm7", "xarm_description/urdf/xarm7.urdf", "xarm_description/srdf/xarm7.srdf", "xarm7"
        ),
        ExampleRobot(
            "kinova",
            "kinova_description/robots/kinova.urdf",
            "kinova_description/srdf/kinova.srdf",
            "end_effector",
        ),
        ExampleRobot(
            "z1", "z1_description/urdf/z1.urdf", "z1_description/srdf/z1.srdf", "end_effector"
        ),
        ExampleRobot(
            "tiago",
            "tiago_description/robots/tiago.urdf",
            joint_names=("torso_lift_joint", *(f"arm_{k}_joint" for k in range(1, 8))),
            base="planar",
        ),
    )
}


def robots_dir() -> Path:
    """The package's robots/ folder; LookupError when `example-robot-data` is not installed."""
    for key in ("purelib", "platlib", "data"):
        base = Path(sysconfig.get_paths()[key])
        for candidate in (
            base / "cmeel.prefix" / "share" / "example-robot-data" / "robots",
            base / "share" / "example-robot-data" / "robots",
        ):
            if candidate.is_dir():
                return candidate
    raise LookupError(
        "example-robot-data is not installed: pip install 'trajcache[robots]' "
        "(or pip install example-robot-data)"
    )
