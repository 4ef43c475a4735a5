"""Key states as the trajectories table stores them: packed float64 and the derived columns."""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np
import numpy.typing as npt

STATE_DTYPE = np.dtype("<f8")


def pack_states(states: npt.ArrayLike) -> bytes:
    """Serialize an (n, dof) array of states as float64 little-endian, row-major."""
    array = np.asarray(states, dtype=np.float64)
    if array.ndim != 2:
        raise ValueError(f"states must be a 2-D (n, dof) array, got shape {array.shape}")
    return np.ascontiguousarray(array, dtype=STATE_DTYPE).tobytes(order="C")


def unpack_states(data: bytes, *, n_states: int, dof: int) -> npt.NDArray[np.float64]:
    """Deserialize bytes from `pack_states` into a writable (n_states, dof) float64 array."""
    expected = n_states * dof * STATE_DTYPE.itemsize
    if len(data) != expected:
        raise ValueError(f"state blob has {len(data)} bytes, expected {expected}")
    array = np.frombuffer(data, dtype=STATE_DTYPE).reshape(n_states, dof)
    return array.astype(np.float64, copy=True)


def trajectory_content_hash(states: npt.ArrayLike) -> str:
    """SHA-256 of a trajectory's shape and packed states (identity for idempotent import)."""
    array = np.asarray(states, dtype=np.float64)
    digest = hashlib.sha256(f"{array.shape[0]}x{array.shape[1]}:".encode())
    digest.update(pack_states(array))
    return digest.hexdigest()


def state_columns(states: npt.ArrayLike) -> dict[str, Any]:
    """The columns a trajectory derives from its key states: the packed states, their count and
    length, start and goal, the prefilter's start/goal x and y, and the content hash."""
    array = np.asarray(states, dtype=np.float64)
    if array.ndim != 2 or array.shape[0] < 2 or array.shape[1] < 1:
        raise ValueError(f"need at least 2 states of dof >= 1, got shape {array.shape}")
    first, last = array[0], array[-1]
    has_y = array.shape[1] > 1
    return {
        "states": pack_states(array),
        "n_states": int(array.shape[0]),
        "dof": int(array.shape[1]),
        "start": first.tolist(),
        "goal": last.tolist(),
        "start_x": float(first[0]),
        "goal_x": float(last[0]),
        "start_y": float(first[1]) if has_y else 0.0,
        "goal_y": float(last[1]) if has_y else 0.0,
        "content_hash": trajectory_content_hash(array),
    }
