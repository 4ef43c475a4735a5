"""bench/ik.py --service: the same poses through a live service's POST /v1/robots/{id}/ik.

Starts `trajcache serve` (loopback, a temporary SQLite database), registers each robot as its
team would (URDF, SRDF, meshes), and asks for each pose with the robot's seed and the default
`avoid_collisions` (an empty scene: the self-collision check runs). The row's times are the
client's round trips; `server_ms_median` is the server's own `timings_ms.total`, `statuses`
counts the answers by status (`in_collision`: the pose is reached only in collision, as a
random target state in self-collision is).
"""

from __future__ import annotations

import io
import zipfile
from collections import Counter
from contextlib import ExitStack
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from harness.service import running_service
from trajcache_client import NO_RETRY, Client


class ServiceSolver:
    """A solver that asks the live service, keeping the server's time of each answer."""

    def __init__(self, robots: list[Any], stack: ExitStack) -> None:
        base = stack.enter_context(running_service())
        self.client = stack.enter_context(Client(base, timeout=60, retry=NO_RETRY))
        self.server_ms: list[float] = []
        self.statuses: Counter[str] = Counter()  # why the unsolved were not solved
        for case in robots:
            model = self.client.register_model(
                case.urdf,
                srdf=case.srdf,
                group=case.group,
                base=case.model.base.value,
                archive=_zipped(case.files) if case.files else None,
            )
            self.client.put_robot(f"ik-{case.name}", model.model_id)

    def __call__(self, case: Any, pose: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
        quaternion = Rotation.from_matrix(pose[:3, :3]).as_quat()
        request = {
            "link": case.link,
            "position": [float(v) for v in pose[:3, 3]],
            "orientation": [float(v) for v in quaternion],
            "seed": [float(v) for v in seed],
        }
        answer = self.client.ik(f"ik-{case.name}", request)
        self.server_ms.append(answer.timings_ms["total"])
        self.statuses[answer.status] += 1
        return np.array(answer.state) if answer.ok and answer.state is not None else None


def _zipped(files: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for path, data in files.items():
            archive.writestr(path, data)
    return buffer.getvalue()
