"""The state space of one model: sampling bounds, metric and steering, as OMPL's `StateSpace`.

A state is (x, y, θ, q1 … qn) for a planar base, (q1 … qn) for a fixed one. θ is an angle
(SO(2)): differences, distances and interpolation take the short way round. `StateSpaceSpec`
holds the sampling bounds (base x, y from the scene's extent; joints from the model's limits)
and may hold some values constant (the base, when a query does not move it). The motion
checker is `planning.motion`; a checked query of both, `planning.query`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import path_length, state_steps, wrap_angle
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import Resolution, interpolate

EMPTY_SCENE_MARGIN_M = 2.0  # base bounds around the query when the scene gives no extent


@dataclass(frozen=True, eq=False)
class StateSpaceSpec:
    """Sampling bounds and metric of one model's states; `held` values never change."""

    model: RobotModel
    lower: FloatArray
    upper: FloatArray
    resolution: Resolution = field(default_factory=Resolution)

    @property
    def planar(self) -> bool:
        """True when the state starts with a planar base pose (x, y, θ)."""
        return self.model.base is BaseType.PLANAR

    @property
    def dof(self) -> int:
        """Length of a state vector."""
        return self.model.dof

    @property
    def held(self) -> NDArray[np.bool_]:
        """Per state value: True when its bounds pin it to one value."""
        return np.asarray(self.upper - self.lower <= 0.0)

    def difference(self, a: FloatArray, b: FloatArray) -> FloatArray:
        """b − a with the base angle taking the short way (works on batches too)."""
        return state_steps(a, b, base=self.model.base)

    def distance(self, a: FloatArray, b: FloatArray) -> float:
        """Euclidean distance in state space, base angle wrapped."""
        return float(np.linalg.norm(self.difference(a, b)))

    def interpolate(self, a: FloatArray, b: FloatArray, t: float) -> FloatArray:
        """The state a fraction `t` of the way from a to b (the short way for θ)."""
        out = np.asarray(a, dtype=float) + t * self.difference(a, b)
        if self.planar:
            out[..., 2] = wrap_angle(out[..., 2])
        return out

    def extend(self, a: FloatArray, b: FloatArray) -> FloatArray:
        """Samples (N, D) of the segment at the paper resolution, a excluded, b included."""
        key = np.stack([np.asarray(a, dtype=float), np.asarray(b, dtype=float)])
        samples = interpolate(key, self.model, self.resolution)[1:]
        if self.planar:
            samples[:, 2] = wrap_angle(samples[:, 2])
        return samples

    def path_length(self, path: Sequence[FloatArray] | FloatArray) -> float:
        """Sum of the distances between consecutive states."""
        return path_length(path, base=self.model.base)

    def clip(self, state: FloatArray) -> FloatArray:
        """The state pulled inside the bounds (θ wrapped rather than clipped)."""
        out = np.asarray(state, dtype=float).copy()
        if self.planar:
            theta = out[..., 2].copy()
            out = np.clip(out, self.lower, self.upper)
            out[..., 2] = self.lower[2] if self.held[2] else wrap_angle(theta)
            return out
        return np.clip(out, self.lower, self.upper)

    def sample(self, rng: np.random.Generator) -> FloatArray:
        """A state drawn uniformly within the bounds."""
        out: FloatArray = self.lower + rng.random(self.dof) * (self.upper - self.lower)
        return out

    def sample_near(
        self, center: FloatArray, radius: float, rng: np.random.Generator
    ) -> FloatArray:
        """A state drawn from an isotropic Gaussian of std `radius` around `center`."""
        step = rng.normal(0.0, radius, self.dof)
        step[self.held] = 0.0
        return self.clip(np.asarray(center, dtype=float) + step)


def scene_extent(scene: Scene) -> tuple[FloatArray, FloatArray] | None:
    """The (x, y) axis-aligned box around every scene object, or None for an empty scene."""
    if not scene.objects:
        return None
    lows, highs = [], []
    for obj in scene.objects:
        reach = np.abs(obj.pose[:3, :3]) @ np.asarray(obj.shape.half_extents(), dtype=float)
        lows.append(obj.pose[:2, 3] - reach[:2])
        highs.append(obj.pose[:2, 3] + reach[:2])
    return np.min(lows, axis=0), np.max(highs, axis=0)


def state_space_spec(
    model: RobotModel,
    scene: Scene | None = None,
    *,
    base_bounds: tuple[Sequence[float], Sequence[float]] | None = None,
    hold_base: FloatArray | None = None,
    around: Sequence[FloatArray] = (),
    resolution: Resolution | None = None,
) -> StateSpaceSpec:
    """Bounds for planning: base (x, y) from `base_bounds`, else the scene's extent; joints from
    the model's limits. `hold_base` pins the base to that (x, y, θ); `around` states are always
    inside the bounds (a start a little outside the scene's extent stays plannable)."""
    lower, upper = model.lower.astype(float).copy(), model.upper.astype(float).copy()
    if model.base is BaseType.PLANAR:
        lower[2], upper[2] = -math.pi, math.pi
        if hold_base is not None:
            held = np.asarray(hold_base, dtype=float)[:3].copy()
            held[2] = float(wrap_angle(held[2]))
            lower[:3] = upper[:3] = held
        else:
            lo, hi = _base_box(scene, base_bounds, around)
            lower[:2], upper[:2] = lo, hi
    return StateSpaceSpec(model, lower, upper, resolution or Resolution())


def _base_box(
    scene: Scene | None,
    base_bounds: tuple[Sequence[float], Sequence[float]] | None,
    around: Sequence[FloatArray],
) -> tuple[FloatArray, FloatArray]:
    points = np.array([np.asarray(s, dtype=float)[:2] for s in around]).reshape(-1, 2)
    if base_bounds is not None:
        lo, hi = np.asarray(base_bounds[0], dtype=float), np.asarray(base_bounds[1], dtype=float)
    else:
        extent = scene_extent(scene) if scene is not None else None
        if extent is not None:
            lo, hi = extent
        elif len(points):
            lo = points.min(axis=0) - EMPTY_SCENE_MARGIN_M
            hi = points.max(axis=0) + EMPTY_SCENE_MARGIN_M
        else:
            lo, hi = np.full(2, -EMPTY_SCENE_MARGIN_M), np.full(2, EMPTY_SCENE_MARGIN_M)
    if len(points):
        lo, hi = np.minimum(lo, points.min(axis=0)), np.maximum(hi, points.max(axis=0))
    return lo, hi
