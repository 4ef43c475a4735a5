"""Distances of convex shapes, compiled: GJK on the support tables, as proved lower bounds.

The distance of convex shapes A and B is that of the origin to their Minkowski difference
A − B. GJK (Gilbert, Johnson and Keerthi) walks a simplex of support points of A − B toward the
origin: v is the simplex's point closest to it, and w = s_A(−v) − s_B(v) the point of A − B
farthest along −v. Whatever v is, every point p of A − B has v·p ≥ v·w, so

    dist(A, B) ≥ v·w / |v|

the slab bound of `slabs.py` along v. The largest such bound met is what is returned: the search
only chooses directions, and a wrong turn (round-off in the simplex, a degenerate simplex) makes
the bound looser, never unsound. Soundness rests on the support points alone: a primitive's is
its formula (centre, box corner, disk rim, ball), a mesh's is the vertex of its hull found by hill
climbing (`model/kernels.hull_vertex`, exact for a convex polytope), so a concave mesh is bounded
by its hull, whose distance never exceeds its own.

It stops when the bound exceeds what the caller needs, when |v| (an upper bound: v is a point of
A − B) is within `TOLERANCE` of it, when v vanishes or the simplex holds the origin (touching or
overlapping: 0, which is a lower bound of any distance), or after `MAX_ITERATIONS` with the
best bound so far. Curved shapes converge in the limit, polytopes in finitely many steps.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from trajcache.geometry.model.kernels import BORROWED, hull_vertex

TOLERANCE = 1e-7  # metres between the bound and |v| where the search stops
MAX_ITERATIONS = 64
_TINY = 1e-14


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def support_point(sup, k, x, y, z):  # type: ignore[no-untyped-def]  # pragma: no cover
    """A point of shape k of a packed support table (`support.SupportTable`) farthest along
    the local direction (x, y, z): a mesh's hull vertex, a primitive's by its formula (the
    centre, plus the box corner on the direction's side, the disk's rim point, the ball's)."""
    centre, packed, slot, vertices, anchors, anchor_start, anchor_count, neighbours, start = sup
    s = slot[k]
    if s >= 0:
        v = hull_vertex(
            vertices, anchors, anchor_start, anchor_count, neighbours, start, s, x, y, z
        )
        return vertices[v, 0], vertices[v, 1], vertices[v, 2]
    px = centre[k, 0] + (packed[k, 0] if x >= 0.0 else -packed[k, 0])
    py = centre[k, 1] + (packed[k, 1] if y >= 0.0 else -packed[k, 1])
    pz = centre[k, 2] + (packed[k, 2] if z >= 0.0 else -packed[k, 2])
    flat = math.sqrt(x * x + y * y)
    if packed[k, 3] > 0.0 and flat > _TINY:
        px += packed[k, 3] * x / flat
        py += packed[k, 3] * y / flat
    norm = math.sqrt(x * x + y * y + z * z)
    if packed[k, 4] > 0.0 and norm > _TINY:
        px += packed[k, 4] * x / norm
        py += packed[k, 4] * y / norm
        pz += packed[k, 4] * z / norm
    return px, py, pz


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _world_support(pose, sup, k, x, y, z):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The world point of shape k posed at `pose` (3 × 4 or 4 × 4) farthest along the world
    direction (x, y, z)."""
    lx = pose[0, 0] * x + pose[1, 0] * y + pose[2, 0] * z
    ly = pose[0, 1] * x + pose[1, 1] * y + pose[2, 1] * z
    lz = pose[0, 2] * x + pose[1, 2] * y + pose[2, 2] * z
    px, py, pz = support_point(sup, k, lx, ly, lz)
    return (
        pose[0, 0] * px + pose[0, 1] * py + pose[0, 2] * pz + pose[0, 3],
        pose[1, 0] * px + pose[1, 1] * py + pose[1, 2] * pz + pose[1, 3],
        pose[2, 0] * px + pose[2, 1] * py + pose[2, 2] * pz + pose[2, 3],
    )


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _dot(s, i, x, y, z):  # type: ignore[no-untyped-def]  # pragma: no cover
    return s[i, 0] * x + s[i, 1] * y + s[i, 2] * z


@numba.njit(cache=True, nogil=True, **BORROWED)
def _triangle(s, a, b, c):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The point of triangle (s[a], s[b], s[c]) closest to the origin, and a bit mask of the
    vertices of the feature it lies on (Ericson, Real-Time Collision Detection, 5.1.5)."""
    abx, aby, abz = s[b, 0] - s[a, 0], s[b, 1] - s[a, 1], s[b, 2] - s[a, 2]
    acx, acy, acz = s[c, 0] - s[a, 0], s[c, 1] - s[a, 1], s[c, 2] - s[a, 2]
    d1, d2 = -_dot(s, a, abx, aby, abz), -_dot(s, a, acx, acy, acz)
    if d1 <= 0.0 and d2 <= 0.0:
        return s[a, 0], s[a, 1], s[a, 2], 1 << a
    d3, d4 = -_dot(s, b, abx, aby, abz), -_dot(s, b, acx, acy, acz)
    if d3 >= 0.0 and d4 <= d3:
        return s[b, 0], s[b, 1], s[b, 2], 1 << b
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3)
        return s[a, 0] + t * abx, s[a, 1] + t * aby, s[a, 2] + t * abz, (1 << a) | (1 << b)
    d5, d6 = -_dot(s, c, abx, aby, abz), -_dot(s, c, acx, acy, acz)
    if d6 >= 0.0 and d5 <= d6:
        return s[c, 0], s[c, 1], s[c, 2], 1 << c
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        return s[a, 0] + t * acx, s[a, 1] + t * acy, s[a, 2] + t * acz, (1 << a) | (1 << c)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        x = s[b, 0] + t * (s[c, 0] - s[b, 0])
        y = s[b, 1] + t * (s[c, 1] - s[b, 1])
        z = s[b, 2] + t * (s[c, 2] - s[b, 2])
        return x, y, z, (1 << b) | (1 << c)
    total = va + vb + vc
    if abs(total) <= _TINY:  # a degenerate triangle: its first edge stands for it
        return _segment(s, a, b)
    v, w = vb / total, vc / total
    x = s[a, 0] + abx * v + acx * w
    y = s[a, 1] + aby * v + acy * w
    z = s[a, 2] + abz * v + acz * w
    return x, y, z, (1 << a) | (1 << b) | (1 << c)


@numba.njit(cache=True, nogil=True, **BORROWED)
def _segment(s, a, b):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The point of segment (s[a], s[b]) closest to the origin, and its feature's mask."""
    dx, dy, dz = s[b, 0] - s[a, 0], s[b, 1] - s[a, 1], s[b, 2] - s[a, 2]
    length = dx * dx + dy * dy + dz * dz
    t = -_dot(s, a, dx, dy, dz) / length if length > _TINY else 1.0
    if t <= 0.0:
        return s[a, 0], s[a, 1], s[a, 2], 1 << a
    if t >= 1.0:
        return s[b, 0], s[b, 1], s[b, 2], 1 << b
    return s[a, 0] + t * dx, s[a, 1] + t * dy, s[a, 2] + t * dz, (1 << a) | (1 << b)


@numba.njit(cache=True, nogil=True, **BORROWED)
def _outside(s, a, b, c, d):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether the origin and s[d] lie on opposite sides of the plane of (s[a], s[b], s[c]),
    or the tetrahedron is flat (then every face is tried)."""
    abx, aby, abz = s[b, 0] - s[a, 0], s[b, 1] - s[a, 1], s[b, 2] - s[a, 2]
    acx, acy, acz = s[c, 0] - s[a, 0], s[c, 1] - s[a, 1], s[c, 2] - s[a, 2]
    nx, ny, nz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
    side_o = -_dot(s, a, nx, ny, nz)
    side_d = (s[d, 0] - s[a, 0]) * nx + (s[d, 1] - s[a, 1]) * ny + (s[d, 2] - s[a, 2]) * nz
    return side_o * side_d < 0.0 or abs(side_d) <= _TINY


@numba.njit(cache=True, nogil=True, **BORROWED)
def _closest(s, n):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The point of the simplex s[:n] closest to the origin, and the mask of the vertices of
    its feature (all four, 15, when a tetrahedron holds the origin)."""
    if n == 1:
        return s[0, 0], s[0, 1], s[0, 2], 1
    if n == 2:
        return _segment(s, 0, 1)
    if n == 3:
        return _triangle(s, 0, 1, 2)
    best = np.inf
    bx = by = bz = 0.0
    mask = 15
    for a, b, c, d in ((0, 1, 2, 3), (0, 1, 3, 2), (0, 2, 3, 1), (1, 2, 3, 0)):
        if _outside(s, a, b, c, d):
            x, y, z, m = _triangle(s, a, b, c)
            if x * x + y * y + z * z < best:
                best, bx, by, bz, mask = x * x + y * y + z * z, x, y, z, m
    return bx, by, bz, mask


@numba.njit(cache=True, nogil=True, **BORROWED)
def _keep(s, n, mask):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Compact s[:n] to the vertices in `mask`; their count."""
    kept = 0
    for i in range(n):
        if mask & (1 << i):
            if kept != i:
                s[kept, 0], s[kept, 1], s[kept, 2] = s[i, 0], s[i, 1], s[i, 2]
            kept += 1
    return kept


@numba.njit(cache=True, nogil=True, **BORROWED)
def convex_lower(pose_a, sup_a, ka, pose_b, sup_b, kb, need, simplex):  # type: ignore[no-untyped-def]  # pragma: no cover
    """A lower bound of the distance between shape ka of `sup_a` at pose_a and shape kb of
    `sup_b` at pose_b (meshes as their hulls), by GJK (the module's docstring): at least
    `need` once it exceeds it, else within `TOLERANCE` of the distance unless the iterations
    run out. `simplex` is scratch space (4 × 3)."""
    vx = pose_a[0, 3] - pose_b[0, 3]
    vy = pose_a[1, 3] - pose_b[1, 3]
    vz = pose_a[2, 3] - pose_b[2, 3]
    if vx * vx + vy * vy + vz * vz <= _TINY:
        vx = 1.0
    lower = 0.0  # a distance is never negative
    n = 0
    for _ in range(MAX_ITERATIONS):
        norm = math.sqrt(vx * vx + vy * vy + vz * vz)
        if norm <= _TINY:
            return lower
        ax, ay, az = _world_support(pose_a, sup_a, ka, -vx, -vy, -vz)
        bx, by, bz = _world_support(pose_b, sup_b, kb, vx, vy, vz)
        wx, wy, wz = ax - bx, ay - by, az - bz
        lower = max(lower, (vx * wx + vy * wy + vz * wz) / norm)
        if lower > need or norm - lower <= TOLERANCE:
            return lower
        simplex[n, 0], simplex[n, 1], simplex[n, 2] = wx, wy, wz
        vx, vy, vz, mask = _closest(simplex, n + 1)
        if mask == 15:  # the origin is inside A − B: they overlap
            return lower
        n = _keep(simplex, n + 1, mask)
    return lower


@numba.njit(cache=True, nogil=True, **BORROWED)
def convex_lower_rows(poses_a, sup_a, index_a, poses_b, sup_b, index_b, need, simplex, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """out[k] = `convex_lower` of shape index_a[k] at poses_a[k] and shape index_b[k] at
    poses_b[k], for every row k, with need[k] (`simplex`: scratch space, 4 × 3)."""
    for k in range(out.shape[0]):
        out[k] = convex_lower(
            poses_a[k], sup_a, index_a[k], poses_b[k], sup_b, index_b[k], need[k], simplex
        )
