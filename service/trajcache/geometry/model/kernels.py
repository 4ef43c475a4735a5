"""The model's compiled kernels (numba, `cache=True`): forward kinematics and the hull climb.

The hull support climb serves the support functions of meshes (`support.py`) and the slabs of
the certification levels (`collision/compiled/`), which build on these. All kernels are compiled
once per machine (numba's on-disk cache, filled by `make setup`) and warmed by `warm()`
(`geometry/warm.py`) when the service starts, so that no request pays for compilation.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from trajcache.geometry import kernel_cache  # noqa: F401  (first: its locators stamp the kernels)
from trajcache.geometry.model.shapes import FloatArray

IntArray = NDArray[np.int64]

# numba options of a kernel that allocates nothing and returns no array: it compiles without
# reference counting, borrowing every array from its caller (`collision/compiled/spheres.py`
# says why; `tests/geometry/test_kernel_refcounts.py` holds the rule). Defined here, in a
# stamped kernel source, as everything the kernels compile in is (`kernel_cache.py`).
BORROWED: dict[str, Any] = {"_nrt": False}


@numba.njit(cache=True, nogil=True, **BORROWED)
def hull_support_climb(
    vertices: FloatArray,
    start: np.ndarray,
    count: np.ndarray,
    anchors: np.ndarray,
    anchor_start: np.ndarray,
    anchor_count: np.ndarray,
    neighbours: np.ndarray,
    neighbour_start: np.ndarray,
    slot: np.ndarray,
    local: FloatArray,
    out: FloatArray,
) -> None:  # pragma: no cover - compiled
    """out[q] = max over the vertices v of hull slot[q] of local[q]·v, for every q with a slot
    ≥ 0 (hull s's vertices packed at vertices[start[s] : start[s] + count[s]]), by hill
    climbing: from the best of the hull's anchor vertices, move to a neighbour (along a hull
    edge) while that raises local[q]·v.

    Exact for a convex polytope: a vertex that no edge improves maximizes a linear function
    over the polytope (the simplex method's optimality argument). `neighbours[neighbour_start[v]
    : neighbour_start[v + 1]]` are the packed indices of the vertices that share an edge with
    packed vertex v; a hull's anchors are packed vertex indices too.
    """
    for q in range(slot.shape[0]):
        s = slot[q]
        if s >= 0:
            out[q] = hull_climb(
                vertices, anchors, anchor_start, anchor_count, neighbours, neighbour_start, s,
                local[q, 0], local[q, 1], local[q, 2],
            )  # fmt: skip


@numba.njit(cache=True, nogil=True, **BORROWED)
def hull_climb(
    vertices: FloatArray,
    anchors: np.ndarray,
    anchor_start: np.ndarray,
    anchor_count: np.ndarray,
    neighbours: np.ndarray,
    neighbour_start: np.ndarray,
    s: int,
    x: float,
    y: float,
    z: float,
) -> float:  # pragma: no cover - compiled
    """max over the vertices v of hull s of (x, y, z)·v, by the climb `hull_support_climb`
    describes (one direction; also called from the certification kernels)."""
    v = hull_vertex(
        vertices, anchors, anchor_start, anchor_count, neighbours, neighbour_start, s, x, y, z
    )
    return x * vertices[v, 0] + y * vertices[v, 1] + z * vertices[v, 2]


@numba.njit(cache=True, nogil=True, **BORROWED)
def hull_vertex(
    vertices: FloatArray,
    anchors: np.ndarray,
    anchor_start: np.ndarray,
    anchor_count: np.ndarray,
    neighbours: np.ndarray,
    neighbour_start: np.ndarray,
    s: int,
    x: float,
    y: float,
    z: float,
) -> int:  # pragma: no cover - compiled
    """The packed index of a vertex of hull s where (x, y, z)·v is largest (`hull_climb`'s
    value; the support point GJK needs, `collision/compiled/gjk.py`)."""
    best = -np.inf
    at = -1
    for a in range(anchor_start[s], anchor_start[s] + anchor_count[s]):
        v = anchors[a]
        value = x * vertices[v, 0] + y * vertices[v, 1] + z * vertices[v, 2]
        if value > best:
            best = value
            at = v
    moved = True
    while moved:
        moved = False
        for n in range(neighbour_start[at], neighbour_start[at + 1]):
            v = neighbours[n]
            value = x * vertices[v, 0] + y * vertices[v, 1] + z * vertices[v, 2]
            if value > best:
                best = value
                at = v
                moved = True
    return at


@numba.njit(cache=True, nogil=True, **BORROWED)
def forward_kinematics_kernel(
    q: FloatArray,
    planar: bool,
    parent: IntArray,
    child: IntArray,
    value_index: IntArray,
    value_scale: FloatArray,
    value_offset: FloatArray,
    default: FloatArray,
    fixed: FloatArray,
    sine: FloatArray,
    versine: FloatArray,
    slide: FloatArray,
    out: FloatArray,
) -> None:  # pragma: no cover - compiled
    """World pose out[n, l] (4 × 4) of every link l at every state q[n].

    Joint j's transform at value v is fixed[j] + sin(v)·sine[j] + (1 − cos(v))·versine[j] +
    v·slide[j] (`kinematics._Tables`); v is q[n, value_index[j]]·scale + offset, or the held
    default when value_index[j] < 0. Joints are in an order where a parent is posed first.
    """
    fx, si, ve, sl = fixed, sine, versine, slide
    for n in range(q.shape[0]):
        out[n, 0, :, :] = 0.0
        for i in range(4):
            out[n, 0, i, i] = 1.0
        if planar:
            c, s = math.cos(q[n, 2]), math.sin(q[n, 2])
            out[n, 0, 0, 0], out[n, 0, 0, 1], out[n, 0, 1, 0], out[n, 0, 1, 1] = c, -s, s, c
            out[n, 0, 0, 3], out[n, 0, 1, 3] = q[n, 0], q[n, 1]
        for j in range(parent.shape[0]):
            if value_index[j] >= 0:
                v = q[n, value_index[j]] * value_scale[j] + value_offset[j]
            else:
                v = default[j]
            sv, cv = (math.sin(v), 1.0 - math.cos(v)) if v != 0.0 else (0.0, 0.0)  # fixed: 0
            top, dst = parent[j], child[j]
            for c in range(4):
                l0 = fx[j, 0, c] + sv * si[j, 0, c] + cv * ve[j, 0, c] + v * sl[j, 0, c]
                l1 = fx[j, 1, c] + sv * si[j, 1, c] + cv * ve[j, 1, c] + v * sl[j, 1, c]
                l2 = fx[j, 2, c] + sv * si[j, 2, c] + cv * ve[j, 2, c] + v * sl[j, 2, c]
                for r in range(3):
                    acc = out[n, top, r, 0] * l0 + out[n, top, r, 1] * l1 + out[n, top, r, 2] * l2
                    out[n, dst, r, c] = acc + (out[n, top, r, 3] if c == 3 else 0.0)
            out[n, dst, 3, 0], out[n, dst, 3, 1], out[n, dst, 3, 2] = 0.0, 0.0, 0.0
            out[n, dst, 3, 3] = 1.0
