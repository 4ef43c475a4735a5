"""The small compiled pieces every kernel shares: poses, world boxes, motion bounds, output rows."""

from __future__ import annotations

import math

import numba
import numpy as np

from trajcache.geometry.model.kernels import BORROWED

ROUNDING = 1e-7  # added to every axis distance (as `motion.axis_distances` does)
GROW = 1024  # rows an output array starts with; `grow` doubles it when full


@numba.njit(cache=True, nogil=True, **BORROWED)
def point_motion(mo, k, a, b, pa, pb, coef, mask):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Bound on the path of a point of a link over segment k, from its world positions pa (at
    sample a) and pb (at b) and its coefficients `coef` (D,) (`motion.MotionBounds.levers`,
    summed); only the dofs where mask > 0 count."""
    step, rotation, rot_index, after, origins, dirs = mo
    total = 0.0
    dof = step.shape[1]
    for d in range(dof):
        if mask[d] <= 0.0 or coef[d] == 0.0:
            continue
        if not rotation[d]:
            total += step[k, d] * coef[d]
            continue
        spread = 0.0
        for d2 in range(dof):
            if after[d, d2]:
                spread += step[k, d2] * coef[d2]
        r = rot_index[d]
        ends = 0.0
        for end in range(2):
            sample = a if end == 0 else b
            p = pa if end == 0 else pb
            ox = p[0] - origins[sample, r, 0]
            oy = p[1] - origins[sample, r, 1]
            oz = p[2] - origins[sample, r, 2]
            along = ox * dirs[sample, r, 0] + oy * dirs[sample, r, 1] + oz * dirs[sample, r, 2]
            square = ox * ox + oy * oy + oz * oz - along * along
            ends += math.sqrt(max(square, 0.0)) + ROUNDING
        total += step[k, d] * min(coef[d], (ends + spread) / 2.0)
    return total


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def turn(step, k, turning, link, mask):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Σ |Δq_d| over the revolute dofs that move `link` (and count under `mask`)."""
    total = 0.0
    for d in range(step.shape[1]):
        if turning[link, d] and mask[d] > 0.0:
            total += step[k, d]
    return total


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def transform_point(pose, x, y, z):  # type: ignore[no-untyped-def]  # pragma: no cover
    """pose (3 × 4) applied to the point (x, y, z)."""
    return (
        pose[0, 0] * x + pose[0, 1] * y + pose[0, 2] * z + pose[0, 3],
        pose[1, 0] * x + pose[1, 1] * y + pose[1, 2] * z + pose[1, 3],
        pose[2, 0] * x + pose[2, 1] * y + pose[2, 2] * z + pose[2, 3],
    )


@numba.njit(cache=True, nogil=True, **BORROWED)
def box_distance(px, py, pz, rot, pos, half):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Distance from a point to an oriented box (rotation, centre, half extents); 0 inside."""
    dx, dy, dz = px - pos[0], py - pos[1], pz - pos[2]
    total = 0.0
    for axis in range(3):
        loc = rot[0, axis] * dx + rot[1, axis] * dy + rot[2, axis] * dz
        out = abs(loc) - half[axis]
        if out > 0.0:
            total += out * out
    return math.sqrt(total)


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def box_distance_at(px, py, pz, rot, pos, half, m):  # type: ignore[no-untyped-def]  # pragma: no cover
    """`box_distance` to box m of (rot (M, 3, 3), pos (M, 3), half (M, 3)), by index: no
    views made in hot loops (numba counts a reference for each)."""
    dx, dy, dz = px - pos[m, 0], py - pos[m, 1], pz - pos[m, 2]
    total = 0.0
    for axis in range(3):
        loc = rot[m, 0, axis] * dx + rot[m, 1, axis] * dy + rot[m, 2, axis] * dz
        out = abs(loc) - half[m, axis]
        if out > 0.0:
            total += out * out
    return math.sqrt(total)


@numba.njit(cache=True, nogil=True)
def pose_all(links, element_link, element_origin, axis_link, axis_local):  # type: ignore[no-untyped-def]  # pragma: no cover
    """World poses (N, E, 3, 4) of every element, and origins and directions (N, R, 3) of the
    revolute axes."""
    n_states, n_el, n_ax = links.shape[0], element_link.shape[0], axis_link.shape[0]
    poses = np.empty((n_states, n_el, 3, 4))
    origins = np.empty((n_states, n_ax, 3))
    dirs = np.empty((n_states, n_ax, 3))
    for n in range(n_states):
        for e in range(n_el):
            frame = links[n, element_link[e]]
            local = element_origin[e]
            for r in range(3):
                for c in range(4):
                    acc = (
                        frame[r, 0] * local[0, c]
                        + frame[r, 1] * local[1, c]
                        + frame[r, 2] * local[2, c]
                    )
                    poses[n, e, r, c] = acc + (frame[r, 3] if c == 3 else 0.0)
        for x in range(n_ax):
            frame = links[n, axis_link[x]]
            u = axis_local[x]
            for r in range(3):
                origins[n, x, r] = frame[r, 3]
                dirs[n, x, r] = frame[r, 0] * u[0] + frame[r, 1] * u[1] + frame[r, 2] * u[2]
    return poses, origins, dirs


@numba.njit(cache=True, nogil=True)
def world_boxes(poses, half, radius):  # type: ignore[no-untyped-def]  # pragma: no cover
    """World boxes (N, E, 3) low and high of every element at every sample: the smaller of the
    boxes about its ball and about its local box (`half` (E, 3) about its origin)."""
    n_states, n_el = poses.shape[0], poses.shape[1]
    lo = np.empty((n_states, n_el, 3))
    hi = np.empty((n_states, n_el, 3))
    for n in range(n_states):
        for e in range(n_el):
            for a in range(3):
                r = (
                    abs(poses[n, e, a, 0]) * half[e, 0]
                    + abs(poses[n, e, a, 1]) * half[e, 1]
                    + abs(poses[n, e, a, 2]) * half[e, 2]
                )
                r = min(r, radius[e])
                lo[n, e, a] = poses[n, e, a, 3] - r
                hi[n, e, a] = poses[n, e, a, 3] + r
    return lo, hi


@numba.njit(cache=True, nogil=True, **BORROWED)
def box_gap(lo_a, hi_a, lo_b, hi_b):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The widest gap between two boxes along an axis: a lower bound on the distance of
    anything inside them (≤ 0 when they overlap)."""
    gap = -np.inf
    for a in range(3):
        gap = max(gap, lo_b[a] - hi_a[a], lo_a[a] - hi_b[a])
    return gap


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def box_gap_at(lo_a, hi_a, n, e, lo_b, hi_b, m):  # type: ignore[no-untyped-def]  # pragma: no cover
    """`box_gap` between box (n, e) of (lo_a, hi_a) (N, E, 3) and box m of (lo_b, hi_b)
    (M, 3), by index."""
    gap = -np.inf
    for a in range(3):
        gap = max(gap, lo_b[m, a] - hi_a[n, e, a], lo_a[n, e, a] - hi_b[m, a])
    return gap


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def box_gap_pair(lo, hi, n, i, j):  # type: ignore[no-untyped-def]  # pragma: no cover
    """`box_gap` between boxes (n, i) and (n, j) of (lo, hi) (N, E, 3), by index."""
    gap = -np.inf
    for a in range(3):
        gap = max(gap, lo[n, j, a] - hi[n, i, a], lo[n, i, a] - hi[n, j, a])
    return gap


@numba.njit(cache=True, nogil=True)
def grow(rows, lows, count):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The output arrays with twice the room once `count` fills them."""
    if count < rows.shape[0]:
        return rows, lows
    more_rows = np.empty((rows.shape[0] * 2, rows.shape[1]), dtype=np.int64)
    more_lows = np.empty((lows.shape[0] * 2, 3))
    more_rows[:count] = rows[:count]
    more_lows[:count] = lows[:count]
    return more_rows, more_lows


@numba.njit(cache=True, nogil=True)
def object_poses(rot_m, pos_m):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Poses (M, 3, 4) of the scene objects from their rotations and positions."""
    pose_obj = np.empty((rot_m.shape[0], 3, 4))
    for m in range(rot_m.shape[0]):
        pose_obj[m, :, :3] = rot_m[m]
        pose_obj[m, :, 3] = pos_m[m]
    return pose_obj


@numba.njit(cache=True, nogil=True, **BORROWED)
def place_cover(links, link, local, count, k, balls, known):  # type: ignore[no-untyped-def]  # pragma: no cover
    """World centres balls[n] (S, 3) of an element's cover balls (centres `local` (S, 3) in the
    frame of `link`) at samples k and k + 1, each sample once (`known`)."""
    for n in range(k, k + 2):
        if not known[n]:
            frame = links[n, link]
            for s in range(count):
                bx, by, bz = transform_point(frame, local[s, 0], local[s, 1], local[s, 2])
                balls[n, s, 0], balls[n, s, 1], balls[n, s, 2] = bx, by, bz
            known[n] = True


@numba.njit(cache=True, nogil=True, **BORROWED)
def cover_motion(mo, k, balls, coef, count, mask, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """out[s]: the motion over segment k of the centre of each cover ball s (`point_motion`)."""
    for s in range(count):
        out[s] = point_motion(mo, k, k, k + 1, balls[k, s], balls[k + 1, s], coef[s], mask)
