"""Compiled kernels (numba, `cache=True`) for the hot loops of the distance bounds.

They are compiled once per machine (numba's on-disk cache) and warmed by `warm()` when the
service starts, so that no request pays for compilation.
"""

from __future__ import annotations

import numba
import numpy as np

from trajcache.geometry.shapes import FloatArray


@numba.njit(cache=True, nogil=True)
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
        if s < 0:
            continue
        x, y, z = local[q, 0], local[q, 1], local[q, 2]
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
        out[q] = best


def warm() -> None:
    """Compile (or load from numba's cache) every kernel now."""
    vertices = np.zeros((1, 3))
    index = np.zeros(1, dtype=np.int64)
    hull_support_climb(
        vertices, index, index + 1, index, index, index + 1, index, np.zeros(2, dtype=np.int64),
        index, np.zeros((1, 3)), np.zeros(1),
    )  # fmt: skip
