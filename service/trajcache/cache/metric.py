"""The paper's similarity metric between two robot states (section 3, eq. 1–2).

A state is a float64 vector: ``(x, y, θ, j1..jn)`` for a planar base or just ``(j1..jn)`` for a
fixed base (`BaseType`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import THETA, TWO_PI, wrap_angle

__all__ = [
    "THETA",
    "TWO_PI",
    "check_dimension",
    "state_distance",
    "wrap_angle",
]


def check_dimension(base: BaseType, dim: int) -> None:
    """Raise ValueError unless states of dimension `dim` can hold a `base` (a planar one's x, y,
    θ come first)."""
    if dim < base.arm_offset:
        raise ValueError(f"states of dimension {dim} cannot hold a {base.value} base")


def state_distance(
    a: npt.ArrayLike, b: npt.ArrayLike, *, base: BaseType
) -> tuple[FloatArray, FloatArray]:
    """Return ``(d_base, d_arm)`` between states ``a`` (..., D) and ``b`` (broadcastable).

    ``d_base = ||p_b − p_a|| + |wrap(θ_b − θ_a)|`` (0 for a fixed base) and
    ``d_arm = max_i |J_b,i − J_a,i|`` over the arm joints (0 when there are none). Both results
    have the broadcast leading shape (0-d arrays for two single states).
    """
    a_arr = np.asarray(a, dtype=np.float64)
    b_arr = np.asarray(b, dtype=np.float64)
    if a_arr.ndim == 0 or b_arr.ndim == 0 or a_arr.shape[-1] != b_arr.shape[-1]:
        raise ValueError(f"state shapes {a_arr.shape} and {b_arr.shape} do not match")
    check_dimension(base, a_arr.shape[-1])
    diff = b_arr - a_arr
    lead = diff.shape[:-1]
    if base is BaseType.PLANAR:
        d_base = np.hypot(diff[..., 0], diff[..., 1]) + np.abs(wrap_angle(diff[..., THETA]))
    else:
        d_base = np.zeros(lead)
    arm = diff[..., base.arm_offset :]
    d_arm = np.abs(arm).max(axis=-1) if arm.shape[-1] else np.zeros(lead)
    return np.asarray(d_base, dtype=np.float64), np.asarray(d_arm, dtype=np.float64)
