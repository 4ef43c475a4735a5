"""The certifier's first try: a chain of samples certified in one compiled call.

`collision/compiled/settle.py` runs the certifier's argument (`certify.py`, `advance.py`) on a
whole chain in compiled code and answers FREE, a certificate of every segment, or leaves the
chain to the certifier's stages, which then run as before. It answers nothing else: collisions,
TOO_CLOSE verdicts and meshes measured as triangles stay with the stages, so a verdict other than
FREE is never the compiled call's.
"""

from __future__ import annotations

import functools

import numpy as np

from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.collision.compiled.settle import settle_kernel
from trajcache.geometry.collision.narrow import EXACT_MARGIN
from trajcache.geometry.model.kinematics import fk_tables
from trajcache.geometry.model.shapes import FloatArray

PROBES = 32  # advancement probes one open pair may take before the stages take over


class ChainSettler:
    """`settle_kernel` for one checker (model and scene), with the certifier's limits."""

    def __init__(self, checker: CollisionChecker, *, min_pad: float, max_depth: int) -> None:
        self.checker = checker
        self.limits = np.array([min_pad, float(max_depth), EXACT_MARGIN, float(PROBES)])

    @functools.cached_property
    def _tables(self) -> tuple[object, ...]:
        """The kernel's arguments past the chain (built on first use: the pairs are final)."""
        checker = self.checker
        robot, world = checker.robot, checker.clearance.scene
        levels = (
            robot.kernel_robot, robot.element_half, robot.support.kernel_args,
            robot.kernel_motion, world.kernel_scene, world.support.kernel_args, checker._allowed,
        )  # fmt: skip
        return (fk_tables(robot.model), levels, checker.kernel_pairs, world.poses, self.limits)

    def free(self, states: FloatArray, delta: FloatArray, step: FloatArray) -> int | None:
        """The advancement probes it took when the compiled call certified every segment of
        checked `states` (N ≥ 2), else None; `delta` and `step` as `certify.py` has them."""
        probes = settle_kernel(
            np.ascontiguousarray(states, dtype=float),
            np.ascontiguousarray(delta, dtype=float),
            np.ascontiguousarray(step, dtype=float),
            *self._tables,
        )
        return None if probes < 0 else int(probes)
