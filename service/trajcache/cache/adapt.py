"""Adapt a cached trajectory to a new request (paper section 3, "Trajectory adaptation").

The first and last states are replaced by the request's start and goal; when the request's base
does not move, every intermediate base pose is re-anchored to the request's base pose.

Heading wrap: states are compared modulo 2π, but the states are then interpolated linearly, so a
substituted endpoint whose θ differs from its neighbour's by more than π would make the robot turn
the long way round. Each substituted endpoint's θ is therefore replaced by the θ + 2πk nearest to
its neighbouring state (the second state for the start, the second-to-last for the goal; for a
two-state trajectory the start is kept as given and the goal is unwrapped towards it). The pose is
the same; only its representation changes, so the returned start/goal may differ from the request's
by a multiple of 2π in θ.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from trajcache.cache.metric import THETA, TWO_PI, check_dimension
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import BASE_STILL_TOLERANCE, base_is_still

__all__ = ["BASE_STILL_TOLERANCE", "adapt_trajectory"]


def _nearest_turn(theta: float, reference: float) -> float:
    """The angle ``theta + 2πk`` closest to ``reference``."""
    turns = round((reference - theta) / TWO_PI)
    return theta + TWO_PI * turns if turns else theta


def adapt_trajectory(
    states: npt.ArrayLike,
    start: npt.ArrayLike,
    goal: npt.ArrayLike,
    *,
    base: BaseType,
    reverse: bool = False,
) -> FloatArray:
    """Return a new (n, D) trajectory from ``states`` that runs exactly from start to goal."""
    path = np.array(states, dtype=np.float64)  # always a copy
    s = np.asarray(start, dtype=np.float64)
    g = np.asarray(goal, dtype=np.float64)
    if path.ndim != 2 or len(path) < 2:
        raise ValueError(f"a trajectory needs at least two states, got shape {path.shape}")
    dim = path.shape[1]
    if s.shape != (dim,) or g.shape != (dim,):
        raise ValueError(f"start/goal must have shape ({dim},); got {s.shape} and {g.shape}")
    check_dimension(base, dim)
    if reverse:
        path = path[::-1].copy()
    if base_is_still(s, g, base):
        path[1:-1, : base.arm_offset] = s[: base.arm_offset]
    path[0] = s
    path[-1] = g
    if base is BaseType.PLANAR:
        if len(path) > 2:
            path[0, THETA] = _nearest_turn(s[THETA], path[1, THETA])
        path[-1, THETA] = _nearest_turn(g[THETA], path[-2, THETA])
    return path
