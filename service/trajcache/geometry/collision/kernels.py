"""Compiled kernels (numba, `cache=True`) for the hot loops of the distance bounds.

The hull support climb lives here; the certification levels and forward kinematics are in
`compiled.py`. All are compiled once per machine (numba's on-disk cache, filled by `make setup`)
and warmed by `warm()` (`geometry/warm.py`) when the service starts, so that no request pays for
compilation.
"""

from __future__ import annotations

import numba
import numpy as np

from trajcache.geometry.model.shapes import FloatArray


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
        if s >= 0:
            out[q] = hull_climb(
                vertices, anchors, anchor_start, anchor_count, neighbours, neighbour_start, s,
                local[q, 0], local[q, 1], local[q, 2],
            )  # fmt: skip


@numba.njit(cache=True, nogil=True)
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
    return best
