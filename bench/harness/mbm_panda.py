"""The MotionBenchMaker Panda registered with a running service as shipped: `robot/panda.urdf`,
`robot/panda.srdf` (group `panda_arm`) and its collision meshes, so every benchmark on the MBM
problems plans for the same model."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

from trajcache_client import Client, RobotModel

GROUP = "panda_arm"
NAME = "panda-mbm"


def mesh_archive(robot_dir: Path) -> bytes:
    """The robot's collision meshes as a zip, by their path below robot/ (`meshes/…`), as the
    URDF's `package://meshes/…` URIs name them."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted((robot_dir / "meshes").rglob("*")):
            if path.is_file():
                archive.writestr(str(path.relative_to(robot_dir)), path.read_bytes())
    return buffer.getvalue()


def register_panda(client: Client, robot_dir: Path) -> RobotModel:
    """Register the Panda of `robot_dir` (the data set's `robot/`) with the service."""
    return client.register_model(
        (robot_dir / "panda.urdf").read_text(encoding="utf-8"),
        srdf=(robot_dir / "panda.srdf").read_text(encoding="utf-8"),
        group=GROUP,
        archive=mesh_archive(robot_dir),
        name=NAME,
    )
