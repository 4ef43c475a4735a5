"""Support functions and slab bounds, compiled: the level-2 bounds of every kernel.

A slab along a direction n bounds the distance of two shapes from below by the gap between
their support planes; meshes count as their bounding boxes, or, `exact`, as their hulls (the
hill climb of `model/kernels.py`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from trajcache.geometry.model.kernels import BORROWED, hull_climb

_TINY = 1e-12
_EXACT_DIRECTIONS = 3  # directions a slab level looks at meshes as hulls along


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def support_at(sup, k, x, y, z, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """h(n) of shape k of a packed support table (`support.SupportTable`) at local direction
    (x, y, z); a mesh as its bounding box unless `exact`, then as its hull (hill climbing)."""
    centre, packed, slot, vertices, anchors, anchor_start, anchor_count, neighbours, start = sup
    value = (  # scalar indexing: no view of packed[k] per call
        abs(x) * packed[k, 0]
        + abs(y) * packed[k, 1]
        + abs(z) * packed[k, 2]
        + packed[k, 3] * math.sqrt(x * x + y * y)
        + packed[k, 4]
        + x * centre[k, 0]
        + y * centre[k, 1]
        + z * centre[k, 2]
    )
    s = slot[k]
    if not exact or s < 0:
        return value
    return hull_climb(vertices, anchors, anchor_start, anchor_count, neighbours, start, s, x, y, z)


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
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


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _keep(value, q, v1, q1, v2, q2, v3, q3):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The best three (value, direction index) after `value` at q is seen (first on ties)."""
    if value > v1:
        return value, q, v1, q1, v2, q2
    if value > v2:
        return v1, q1, value, q, v2, q2
    if value > v3:
        return v1, q1, v2, q2, value, q
    return v1, q1, v2, q2, v3, q3


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _scene_direction(q, pose_e, pose_m, half):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Direction q of `scene_slabs`: 0-11 the box's and the element's face normals (each
    axis, each sign, box first), 12 the way from the element's origin to the nearest point
    of the object's box (local = R_mᵀ(t_e − t_m), clipped into the box)."""
    if q < 12:
        axis, rest = q // 4, q % 4
        sign = -1.0 if rest < 2 else 1.0
        pose = pose_m if rest % 2 == 0 else pose_e
        return sign * pose[0, axis], sign * pose[1, axis], sign * pose[2, axis]
    dx = pose_e[0, 3] - pose_m[0, 3]
    dy = pose_e[1, 3] - pose_m[1, 3]
    dz = pose_e[2, 3] - pose_m[2, 3]
    x = y = z = 0.0
    for axis in range(3):
        loc = pose_m[0, axis] * dx + pose_m[1, axis] * dy + pose_m[2, axis] * dz
        gap = min(max(loc, -half[axis]), half[axis]) - loc
        x += pose_m[0, axis] * gap
        y += pose_m[1, axis] * gap
        z += pose_m[2, axis] * gap
    return x, y, z


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _self_direction(q, pose_i, pose_j):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Direction q of `self_slabs`: 0 the line between the elements, 1 and 2 across both z
    axes (both ways), 3-14 both elements' face normals (each axis, each sign, i first)."""
    if q == 0:
        return pose_j[0, 3] - pose_i[0, 3], pose_j[1, 3] - pose_i[1, 3], pose_j[2, 3] - pose_i[2, 3]
    if q < 3:
        sign = 1.0 if q == 1 else -1.0
        x = pose_i[1, 2] * pose_j[2, 2] - pose_i[2, 2] * pose_j[1, 2]
        y = pose_i[2, 2] * pose_j[0, 2] - pose_i[0, 2] * pose_j[2, 2]
        z = pose_i[0, 2] * pose_j[1, 2] - pose_i[1, 2] * pose_j[0, 2]
        return sign * x, sign * y, sign * z
    axis, rest = (q - 3) // 4, (q - 3) % 4
    sign = -1.0 if rest < 2 else 1.0
    pose = pose_i if rest % 2 == 0 else pose_j
    return sign * pose[0, axis], sign * pose[1, axis], sign * pose[2, axis]


_SCENE_DIRECTIONS, _SELF_DIRECTIONS = 13, 15


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _best_slab(pose_a, sup_a, ka, pose_b, sup_b, kb, half, count, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The max of the slab bounds along the `count` directions of `scene_slabs` (13, `half` the
    object's box) or `self_slabs` (15), meshes as their boxes; with `exact`, also along the
    best three of them with meshes as their hulls (a hull's bound along a direction is at
    least its box's, and the best exact direction is nearly always among the best box ones).
    No arrays are allocated: the directions are computed where they are used."""
    best = v1 = v2 = v3 = -np.inf
    q1 = q2 = q3 = -1
    for q in range(count):
        x, y, z = _direction(q, count, pose_a, pose_b, half)
        value = slab_bound(x, y, z, pose_a, sup_a, ka, pose_b, sup_b, kb, False)
        best = max(best, value)
        v1, q1, v2, q2, v3, q3 = _keep(value, q, v1, q1, v2, q2, v3, q3)
    best = max(best, 0.0)
    if not exact or (sup_a[2][ka] < 0 and sup_b[2][kb] < 0):
        return best
    for q in (q1, q2, q3):
        x, y, z = _direction(q, count, pose_a, pose_b, half)
        best = max(best, slab_bound(x, y, z, pose_a, sup_a, ka, pose_b, sup_b, kb, True))
    return best


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _direction(q, count, pose_a, pose_b, half):  # type: ignore[no-untyped-def]  # pragma: no cover
    if count == _SCENE_DIRECTIONS:
        return _scene_direction(q, pose_a, pose_b, half)
    return _self_direction(q, pose_a, pose_b)


@numba.njit(cache=True, nogil=True, **BORROWED)
def scene_slabs(pose_e, sup_r, e, pose_m, sup_s, m, half, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Level 2 for an element and an object (`_best_slab`): along the box's and the element's
    face normals and the way from the element's origin to the nearest point of the object's
    box (`_scene_direction`)."""
    return _best_slab(pose_e, sup_r, e, pose_m, sup_s, m, half, _SCENE_DIRECTIONS, exact)


@numba.njit(cache=True, nogil=True, **BORROWED)
def self_slabs(pose_i, pose_j, sup, i, j, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Level 2 for a robot pair (`_best_slab`): along the line between the elements, across
    both z axes (both ways) and both elements' face normals (`_self_direction`)."""
    return _best_slab(pose_i, sup, i, pose_j, sup, j, pose_i[0], _SELF_DIRECTIONS, exact)
