"""The paper's similarity metric between two robot states (section 3, eq. 1–2).

A state is a float64 vector: ``(x, y, θ, j1..jn)`` for a planar base (``arm_offset=3``) or just
``(j1..jn)`` for a fixed base (``arm_offset=0``).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import THETA, TWO_PI, wrap_angle

PLANAR_ARM_OFFSET = 3

__all__ = [
    "THETA",
    "TWO_PI",
    "base_type",
    "check_arm_offset",
    "state_distance",
    "wrap_angle",
]


def base_type(arm_offset: int) -> BaseType:
    """The kind of base whose states have their arm from `arm_offset` (0 or 3) on."""
    check_arm_offset(arm_offset)
    return BaseType.PLANAR if arm_offset == PLANAR_ARM_OFFSET else BaseType.FIXED


def check_arm_offset(arm_offset: int, dim: int | None = None) -> None:
    """Raise ValueError unless ``arm_offset`` is 0 (fixed base) or 3 (planar base) and fits dim."""
    if arm_offset not in (0, PLANAR_ARM_OFFSET):
        raise ValueError(f"arm_offset must be 0 (fixed base) or 3 (planar base), not {arm_offset}")
    if dim is not None and dim < arm_offset:
        raise ValueError(f"states of dimension {dim} cannot hold a planar base (arm_offset=3)")


def state_distance(
    a: npt.ArrayLike, b: npt.ArrayLike, *, arm_offset: int
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
    check_arm_offset(arm_offset, a_arr.shape[-1])
    diff = b_arr - a_arr
    lead = diff.shape[:-1]
    if arm_offset == PLANAR_ARM_OFFSET:
        d_base = np.hypot(diff[..., 0], diff[..., 1]) + np.abs(wrap_angle(diff[..., THETA]))
    else:
        d_base = np.zeros(lead)
    arm = diff[..., arm_offset:]
    d_arm = np.abs(arm).max(axis=-1) if arm.shape[-1] else np.zeros(lead)
    return np.asarray(d_base, dtype=np.float64), np.asarray(d_arm, dtype=np.float64)
