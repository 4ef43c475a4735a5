"""Support functions and slab bounds, compiled: the level-2 bounds of every kernel.

A slab along a direction n bounds the distance of two shapes from below by the gap between
their support planes; meshes count as their bounding boxes, or, `exact`, as their hulls (the
hill climb of `model/kernels.py`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from trajcache.geometry.model.kernels import hull_climb

_TINY = 1e-12
_EXACT_DIRECTIONS = 3  # directions a slab level looks at meshes as hulls along


@numba.njit(cache=True, nogil=True, inline="always")
def support_at(sup, k, x, y, z, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """h(n) of shape k of a packed support table (`support.SupportTable`) at local direction
    (x, y, z); a mesh as its bounding box unless `exact`, then as its hull (hill climbing)."""
    centre, packed, slot, vertices, anchors, anchor_start, anchor_count, neighbours, start = sup
    p = packed[k]
    value = (
        abs(x) * p[0]
        + abs(y) * p[1]
        + abs(z) * p[2]
        + p[3] * math.sqrt(x * x + y * y)
        + p[4]
        + x * centre[k, 0]
        + y * centre[k, 1]
        + z * centre[k, 2]
    )
    s = slot[k]
    if not exact or s < 0:
        return value
    return hull_climb(vertices, anchors, anchor_start, anchor_count, neighbours, start, s, x, y, z)


@numba.njit(cache=True, nogil=True, inline="always")
def slab_bound(nx, ny, nz, pose_a, sup_a, ka, pose_b, sup_b, kb, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The slab bound along world direction n (any length; zero gives 0) between shape ka of
    `sup_a` at pose_a (3 × 4) and shape kb of `sup_b` at pose_b: the width of the gap between
    their support planes, n·t_B − h_B(−R_Bᵀn) − n·t_A − h_A(R_Aᵀn), for unit n."""
    norm = math.sqrt(nx * nx + ny * ny + nz * nz)
    if norm <= _TINY:
        return 0.0
    nx, ny, nz = nx / norm, ny / norm, nz / norm
    ax = pose_a[0, 0] * nx + pose_a[1, 0] * ny + pose_a[2, 0] * nz
    ay = pose_a[0, 1] * nx + pose_a[1, 1] * ny + pose_a[2, 1] * nz
    az = pose_a[0, 2] * nx + pose_a[1, 2] * ny + pose_a[2, 2] * nz
    bx = -(pose_b[0, 0] * nx + pose_b[1, 0] * ny + pose_b[2, 0] * nz)
    by = -(pose_b[0, 1] * nx + pose_b[1, 1] * ny + pose_b[2, 1] * nz)
    bz = -(pose_b[0, 2] * nx + pose_b[1, 2] * ny + pose_b[2, 2] * nz)
    gap = (
        nx * (pose_b[0, 3] - pose_a[0, 3])
        + ny * (pose_b[1, 3] - pose_a[1, 3])
        + nz * (pose_b[2, 3] - pose_a[2, 3])
    )
    return gap - support_at(sup_a, ka, ax, ay, az, exact) - support_at(sup_b, kb, bx, by, bz, exact)


@numba.njit(cache=True, nogil=True)
def best_slab(dirs, pose_a, sup_a, ka, pose_b, sup_b, kb, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """max over the directions `dirs` (Q, 3) of the slab bound, meshes as their boxes; with
    `exact`, also along the best few of them with meshes as their hulls (a hull's bound along a
    direction is at least its box's, and the best exact direction is nearly always among the
    best box ones)."""
    count = dirs.shape[0]
    values = np.empty(count)
    best = 0.0
    for q in range(count):
        values[q] = slab_bound(
            dirs[q, 0], dirs[q, 1], dirs[q, 2], pose_a, sup_a, ka, pose_b, sup_b, kb, False
        )
        best = max(best, values[q])
    if not exact or (sup_a[2][ka] < 0 and sup_b[2][kb] < 0):
        return best
    for _round in range(min(_EXACT_DIRECTIONS, count)):
        pick = np.argmax(values)
        values[pick] = -np.inf
        value = slab_bound(
            dirs[pick, 0], dirs[pick, 1], dirs[pick, 2], pose_a, sup_a, ka, pose_b, sup_b, kb, True
        )
        best = max(best, value)
    return best


@numba.njit(cache=True, nogil=True)
def scene_slabs(pose_e, sup_r, e, pose_m, sup_s, m, half, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Level 2 for an element and an object: the box's and the element's face normals and the
    way from the element's origin to the nearest point of the object's box (`best_slab`)."""
    dirs = np.empty((13, 3))
    q = 0
    for axis in range(3):
        for sign in (-1.0, 1.0):
            for r in range(3):
                dirs[q, r] = sign * pose_m[r, axis]
                dirs[q + 1, r] = sign * pose_e[r, axis]
            q += 2
    # toward the nearest box point: local = R_mᵀ(t_e − t_m), clipped into the box
    dx = pose_e[0, 3] - pose_m[0, 3]
    dy = pose_e[1, 3] - pose_m[1, 3]
    dz = pose_e[2, 3] - pose_m[2, 3]
    dirs[12, :] = 0.0
    for axis in range(3):
        loc = pose_m[0, axis] * dx + pose_m[1, axis] * dy + pose_m[2, axis] * dz
        gap = min(max(loc, -half[axis]), half[axis]) - loc
        for r in range(3):
            dirs[12, r] += pose_m[r, axis] * gap
    return best_slab(dirs, pose_e, sup_r, e, pose_m, sup_s, m, exact)


@numba.njit(cache=True, nogil=True)
def self_slabs(pose_i, pose_j, sup, i, j, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Level 2 for a robot pair: the line between the elements, across both z axes (both ways)
    and both elements' face normals (`best_slab`)."""
    dirs = np.empty((15, 3))
    for r in range(3):
        dirs[0, r] = pose_j[r, 3] - pose_i[r, 3]
    dirs[1, 0] = pose_i[1, 2] * pose_j[2, 2] - pose_i[2, 2] * pose_j[1, 2]
    dirs[1, 1] = pose_i[2, 2] * pose_j[0, 2] - pose_i[0, 2] * pose_j[2, 2]
    dirs[1, 2] = pose_i[0, 2] * pose_j[1, 2] - pose_i[1, 2] * pose_j[0, 2]
    dirs[2, :] = -dirs[1, :]
    q = 3
    for axis in range(3):
        for sign in (-1.0, 1.0):
            for r in range(3):
                dirs[q, r] = sign * pose_i[r, axis]
                dirs[q + 1, r] = sign * pose_j[r, axis]
            q += 2
    return best_slab(dirs, pose_i, sup, i, pose_j, sup, j, exact)
