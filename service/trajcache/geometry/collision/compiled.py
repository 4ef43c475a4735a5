"""The certification levels compiled: every segment, pair and cover ball in one call per batch.

`validation/certify.py` settles pairs level by level in numpy (element balls, support-function
slabs, the sphere covers and the slabs they suggest); the same levels, with the same bounds, run
here as numba kernels with no Python per segment, pair or ball. What they leave open, the few pairs
no level settles, goes on to the same FCL-directed slab and conservative advancement as before.

Per segment k (samples a, b) and pair, with lower bounds d_a, d_b at the ends and a bound M on
how far any point of the pair moves relative to the other over the segment, d_a + d_b > M
certifies the pair on the segment (`validation/certify.py`). The levels, cheapest first:

1. the element's ball around its origin, the motion of that origin (configuration-independent
   coefficients; `model/motion.py`);
2. slabs along the box's and the element's face normals and toward the nearest box point (for a
   robot pair: the line between the elements, across both their z axes, both elements' face
   normals), meshes first as their bounding boxes, then as their hulls along the three best of
   those directions; the motion of the whole element, first configuration-independent, then
   from the axis distances at both ends;
3. every ball of the element's sphere cover with the motion of its own centre; when a ball is
   not settled, slabs along the ways the four closest balls look to the box (for a pair,
   between the four closest pairs of balls) with the whole element's motion.

Scene objects whose bounding box the element cannot reach within the segment (its ball grown by
its whole motion, from both ends) are settled by that alone.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.kernels import hull_climb
from trajcache.geometry.model.shapes import FloatArray

IntArray = NDArray[np.int64]

_ROUNDING = 1e-7  # added to every axis distance (as `motion.axis_distances` does)
_TINY = 1e-12
_GROW = 1024
_COVER_SLABS = 4  # slabs along the ways of the closest cover balls, per end
_EXACT_DIRECTIONS = 3  # directions a slab level looks at meshes as hulls along


# --- forward kinematics ------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
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
    local = np.empty((4, 4))
    for n in range(q.shape[0]):
        root = out[n, 0]
        root[:, :] = 0.0
        for i in range(4):
            root[i, i] = 1.0
        if planar:
            c, s = math.cos(q[n, 2]), math.sin(q[n, 2])
            root[0, 0], root[0, 1], root[1, 0], root[1, 1] = c, -s, s, c
            root[0, 3], root[1, 3] = q[n, 0], q[n, 1]
        for j in range(parent.shape[0]):
            if value_index[j] >= 0:
                v = q[n, value_index[j]] * value_scale[j] + value_offset[j]
            else:
                v = default[j]
            sv, cv = math.sin(v), 1.0 - math.cos(v)
            for r in range(3):
                for c in range(4):
                    local[r, c] = (
                        fixed[j, r, c]
                        + sv * sine[j, r, c]
                        + cv * versine[j, r, c]
                        + v * slide[j, r, c]
                    )
            top = out[n, parent[j]]
            dst = out[n, child[j]]
            for r in range(3):
                for c in range(4):
                    acc = (
                        top[r, 0] * local[0, c] + top[r, 1] * local[1, c] + top[r, 2] * local[2, c]
                    )
                    if c == 3:
                        acc += top[r, 3]
                    dst[r, c] = acc
            dst[3, 0], dst[3, 1], dst[3, 2], dst[3, 3] = 0.0, 0.0, 0.0, 1.0


# --- support functions and slabs ---------------------------------------------------------------


@numba.njit(cache=True, nogil=True, inline="always")
def _support(sup, k, x, y, z, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
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
def _slab(nx, ny, nz, pose_a, sup_a, ka, pose_b, sup_b, kb, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
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
    return gap - _support(sup_a, ka, ax, ay, az, exact) - _support(sup_b, kb, bx, by, bz, exact)


@numba.njit(cache=True, nogil=True)
def _best_slab(dirs, pose_a, sup_a, ka, pose_b, sup_b, kb, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """max over the directions `dirs` (Q, 3) of the slab bound, meshes as their boxes; with
    `exact`, also along the best few of them with meshes as their hulls (a hull's bound along a
    direction is at least its box's, and the best exact direction is nearly always among the
    best box ones)."""
    count = dirs.shape[0]
    values = np.empty(count)
    best = 0.0
    for q in range(count):
        values[q] = _slab(
            dirs[q, 0], dirs[q, 1], dirs[q, 2], pose_a, sup_a, ka, pose_b, sup_b, kb, False
        )
        best = max(best, values[q])
    if not exact or (sup_a[2][ka] < 0 and sup_b[2][kb] < 0):
        return best
    for _round in range(min(_EXACT_DIRECTIONS, count)):
        pick = np.argmax(values)
        values[pick] = -np.inf
        value = _slab(
            dirs[pick, 0], dirs[pick, 1], dirs[pick, 2], pose_a, sup_a, ka, pose_b, sup_b, kb, True
        )
        best = max(best, value)
    return best


@numba.njit(cache=True, nogil=True)
def _scene_slabs(pose_e, sup_r, e, pose_m, sup_s, m, half, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Level 2 for an element and an object: the box's and the element's face normals and the
    way from the element's origin to the nearest point of the object's box (`_best_slab`)."""
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
    return _best_slab(dirs, pose_e, sup_r, e, pose_m, sup_s, m, exact)


@numba.njit(cache=True, nogil=True)
def _self_slabs(pose_i, pose_j, sup, i, j, exact):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Level 2 for a robot pair: the line between the elements, across both z axes (both ways)
    and both elements' face normals (`_best_slab`)."""
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
    return _best_slab(dirs, pose_i, sup, i, pose_j, sup, j, exact)


# --- motion bounds -----------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def _point_motion(mo, k, a, b, pa, pb, coef, mask):  # type: ignore[no-untyped-def]  # pragma: no cover
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
            ends += math.sqrt(max(square, 0.0)) + _ROUNDING
        total += step[k, d] * min(coef[d], (ends + spread) / 2.0)
    return total


@numba.njit(cache=True, nogil=True, inline="always")
def _turn(step, k, turning, link, mask):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Σ |Δq_d| over the revolute dofs that move `link` (and count under `mask`)."""
    total = 0.0
    for d in range(step.shape[1]):
        if turning[link, d] and mask[d] > 0.0:
            total += step[k, d]
    return total


@numba.njit(cache=True, nogil=True, inline="always")
def _transform(pose, x, y, z):  # type: ignore[no-untyped-def]  # pragma: no cover
    """pose (3 × 4) applied to the point (x, y, z)."""
    return (
        pose[0, 0] * x + pose[0, 1] * y + pose[0, 2] * z + pose[0, 3],
        pose[1, 0] * x + pose[1, 1] * y + pose[1, 2] * z + pose[1, 3],
        pose[2, 0] * x + pose[2, 1] * y + pose[2, 2] * z + pose[2, 3],
    )


@numba.njit(cache=True, nogil=True)
def _box_distance(px, py, pz, rot, pos, half):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Distance from a point to an oriented box (rotation, centre, half extents); 0 inside."""
    dx, dy, dz = px - pos[0], py - pos[1], pz - pos[2]
    total = 0.0
    for axis in range(3):
        loc = rot[0, axis] * dx + rot[1, axis] * dy + rot[2, axis] * dz
        out = abs(loc) - half[axis]
        if out > 0.0:
            total += out * out
    return math.sqrt(total)


@numba.njit(cache=True, nogil=True)
def _pose_all(links, element_link, element_origin, axis_link, axis_local):  # type: ignore[no-untyped-def]  # pragma: no cover
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
def _world_boxes(poses, half, radius):  # type: ignore[no-untyped-def]  # pragma: no cover
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


@numba.njit(cache=True, nogil=True)
def _box_gap(lo_a, hi_a, lo_b, hi_b):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The widest gap between two boxes along an axis: a lower bound on the distance of
    anything inside them (≤ 0 when they overlap)."""
    gap = -np.inf
    for a in range(3):
        gap = max(gap, lo_b[a] - hi_a[a], lo_a[a] - hi_b[a])
    return gap


@numba.njit(cache=True, nogil=True)
def _grow(rows, lows, count):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The output arrays with twice the room once `count` fills them."""
    if count < rows.shape[0]:
        return rows, lows
    more_rows = np.empty((rows.shape[0] * 2, rows.shape[1]), dtype=np.int64)
    more_lows = np.empty((lows.shape[0] * 2, 3))
    more_rows[:count] = rows[:count]
    more_lows[:count] = lows[:count]
    return more_rows, more_lows


# --- the scene levels ---------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def _scene_bound(n, want, ball, low, level, poses, e, radius, sup_r, pose_m, sup_s, m, scene):  # type: ignore[no-untyped-def]  # pragma: no cover
    """A lower bound for element e and object m at sample n: with `want` 1, of the element's
    ball (whose points move as its centre does); with 2, of the element itself, by slabs with
    meshes as boxes; with 3, by slabs with meshes as hulls. Cached in ball[n] (−1: not yet) and
    low[n], level[n] (0: not yet)."""
    pose = poses[n, e]
    rot_m, pos_m, half_m = scene[0], scene[1], scene[2]
    if ball[n] < 0.0:
        gap = _box_distance(pose[0, 3], pose[1, 3], pose[2, 3], rot_m[m], pos_m[m], half_m[m])
        ball[n] = max(gap - radius[e], 0.0)
    if want == 1:
        return ball[n]
    if level[n] < 2:
        low[n] = max(ball[n], _scene_slabs(pose, sup_r, e, pose_m, sup_s, m, half_m[m], False))
        level[n] = 2
    if want >= 3 and level[n] < 3:
        if sup_r[2][e] >= 0 or sup_s[2][m] >= 0:
            low[n] = max(low[n], _scene_slabs(pose, sup_r, e, pose_m, sup_s, m, half_m[m], True))
        level[n] = 3
    return low[n]


@numba.njit(cache=True, nogil=True)
def scene_open_kernel(  # type: ignore[no-untyped-def]  # pragma: no cover
    links, step, robot, half, sup_r, motion, scene, sup_s, allowed, first_only
):
    """Rows (K, 3) (segment, element, object) that levels 1-3 leave open on the segments
    between consecutive samples of `links` (N, L, 4, 4) (segment k: sample k to k + 1, steps
    `step` (N − 1, D) from `MotionBounds.steps`), with (K, 3) lower bounds at both ends and the
    motion bound (`OpenPairs`).

    Motion bounds add up along a path, so a lower bound d at sample n certifies every following
    segment up to the one where the summed motion from n reaches d (conservative advancement
    over the samples, the ball's bound first, then the slabs'); a segment that the bound at its
    start does not reach past is tried on its own, from both ends and with the dearer levels.

    robot: element link, element origin, ball radius, centre coefficients (E, D), turning (L, D),
    cover ball counts, centres in link frames (E, S, 3), radii (E, S), coefficients (E, S, D);
    motion: rotation (D,), rotation index (D,), after (D, D), axis link (R,), axis local (R, 3);
    scene: rotation (M, 3, 3), position, half extents, AABB low and high (M, 3). With
    `first_only`, it returns as soon as it finds one open row.
    """
    link_of, origin, radius, centre_coef, turning, count, sph_local, sph_rad, sph_coef = robot
    rotation, rot_index, after, axis_link, axis_local = motion
    rot_m, pos_m, half_m, lo_m, hi_m = scene
    poses, origins, dirs = _pose_all(links, link_of, origin, axis_link, axis_local)
    box_lo, box_hi = _world_boxes(poses, half, radius)
    mo = (step, rotation, rot_index, after, origins, dirs)
    n_el, n_obj, dof = link_of.shape[0], rot_m.shape[0], step.shape[1]
    n_samples = links.shape[0]
    n_seg = n_samples - 1
    width = sph_rad.shape[1]
    ones = np.ones(dof)
    pose_obj = np.empty((n_obj, 3, 4))
    for m in range(n_obj):
        pose_obj[m, :, :3] = rot_m[m]
        pose_obj[m, :, 3] = pos_m[m]
    rows = np.empty((_GROW, 3), dtype=np.int64)
    lows = np.empty((_GROW, 3))
    found = 0
    centre_sum = np.zeros(n_samples)
    whole_sum = np.zeros(n_samples)
    turns = np.empty(max(n_seg, 1))
    dependent = np.empty(max(n_seg, 1))
    low = np.empty(n_samples)
    level = np.empty(n_samples, dtype=np.int64)
    balls = np.empty((n_samples, width, 3))
    balls_known = np.empty(n_samples, dtype=np.bool_)
    ball_motion = np.empty((max(n_seg, 1), width))
    cover = np.empty((2, width))
    motion_known = np.empty(max(n_seg, 1), dtype=np.bool_)
    ball_low = np.empty(n_samples)
    for e in range(n_el):
        link = link_of[e]
        widest = 0.0
        for k in range(n_seg):
            centre = 0.0
            for d in range(dof):
                centre += step[k, d] * centre_coef[e, d]
            turns[k] = _turn(step, k, turning, link, ones)
            whole = centre + radius[e] * turns[k]
            centre_sum[k + 1] = centre_sum[k] + centre
            whole_sum[k + 1] = whole_sum[k] + whole
            widest = max(widest, whole)
        # every point of the element stays within radius + widest of its origin at a sample
        reach = radius[e] + widest
        lo_x, lo_y, lo_z = np.inf, np.inf, np.inf
        hi_x, hi_y, hi_z = -np.inf, -np.inf, -np.inf
        for n in range(n_samples):
            x, y, z = poses[n, e, 0, 3], poses[n, e, 1, 3], poses[n, e, 2, 3]
            lo_x, lo_y, lo_z = min(lo_x, x), min(lo_y, y), min(lo_z, z)
            hi_x, hi_y, hi_z = max(hi_x, x), max(hi_y, y), max(hi_z, z)
        dependent[:] = -1.0
        balls_known[:] = False
        motion_known[:] = False
        for m in range(n_obj):
            if allowed.shape[0] and allowed[e, m]:
                continue
            if (
                lo_m[m, 0] > hi_x + reach
                or hi_m[m, 0] < lo_x - reach
                or lo_m[m, 1] > hi_y + reach
                or hi_m[m, 1] < lo_y - reach
                or lo_m[m, 2] > hi_z + reach
                or hi_m[m, 2] < lo_z - reach
            ):
                continue
            ball_low[:] = -1.0
            level[:] = 0
            at = 0  # every segment before sample `at` is certified
            while at < n_seg:
                # ahead from `at` while the summed motion stays below the bound there
                ahead = at
                d = _scene_bound(
                    at,
                    1,
                    ball_low,
                    low,
                    level,
                    poses,
                    e,
                    radius,
                    sup_r,
                    pose_obj[m],
                    sup_s,
                    m,
                    scene,
                )
                while ahead < n_seg and centre_sum[ahead + 1] - centre_sum[at] < d:
                    ahead += 1
                if ahead == at:  # the world boxes' gap, with the motion of any point
                    d = _box_gap(box_lo[at, e], box_hi[at, e], lo_m[m], hi_m[m])
                    while ahead < n_seg and whole_sum[ahead + 1] - whole_sum[at] < d:
                        ahead += 1
                if ahead == at:
                    d = _scene_bound(
                        at, 3, ball_low, low, level, poses, e, radius, sup_r, pose_obj[m], sup_s, m,
                        scene,
                    )  # fmt: skip
                    while ahead < n_seg and whole_sum[ahead + 1] - whole_sum[at] < d:
                        ahead += 1
                if ahead > at:
                    at = ahead
                    continue
                # segment `at` on its own, from both ends
                lo, hi = at, at + 1
                at += 1
                settled = False
                moving = whole_sum[hi] - whole_sum[lo]
                box_a = _box_gap(box_lo[lo, e], box_hi[lo, e], lo_m[m], hi_m[m])
                box_b = _box_gap(box_lo[hi, e], box_hi[hi, e], lo_m[m], hi_m[m])
                if box_a + box_b > moving:
                    continue
                for want in range(1, 4):
                    da = _scene_bound(
                        lo, want, ball_low, low, level, poses, e, radius, sup_r, pose_obj[m], sup_s,
                        m, scene,
                    )  # fmt: skip
                    db = _scene_bound(
                        hi, want, ball_low, low, level, poses, e, radius, sup_r, pose_obj[m], sup_s,
                        m, scene,
                    )  # fmt: skip
                    limit = centre_sum[hi] - centre_sum[lo] if want == 1 else moving
                    if da + db > limit:
                        settled = True
                        break
                if settled:
                    continue
                k = lo
                if dependent[k] < 0.0:
                    pa, pb = poses[k, e], poses[k + 1, e]
                    dependent[k] = min(
                        moving,
                        _point_motion(
                            mo, k, k, k + 1, (pa[0, 3], pa[1, 3], pa[2, 3]),
                            (pb[0, 3], pb[1, 3], pb[2, 3]), centre_coef[e], ones,
                        )
                        + radius[e] * turns[k],
                    )  # fmt: skip
                moving = dependent[k]
                if da + db > moving:
                    continue
                if da <= 0.0 or db <= 0.0:
                    # an end in contact, or too close to tell: FCL's collision test decides it
                    # before anything finer is worth computing (`certify._sample_collision`)
                    rows, lows = _grow(rows, lows, found)
                    rows[found, 0], rows[found, 1], rows[found, 2] = k, e, m
                    lows[found, 0], lows[found, 1], lows[found, 2] = da, db, moving
                    found += 1
                    if first_only:
                        return rows[:found], lows[:found]
                    continue
                # level 3: the sphere cover
                for n in range(k, k + 2):
                    if not balls_known[n]:
                        frame = links[n, link]
                        for s in range(count[e]):
                            bx, by, bz = _transform(
                                frame, sph_local[e, s, 0], sph_local[e, s, 1], sph_local[e, s, 2]
                            )
                            balls[n, s, 0], balls[n, s, 1], balls[n, s, 2] = bx, by, bz
                        balls_known[n] = True
                low_a, low_b, touching = np.inf, np.inf, False
                for s in range(count[e]):
                    sa = _box_distance(
                        balls[k, s, 0],
                        balls[k, s, 1],
                        balls[k, s, 2],
                        rot_m[m],
                        pos_m[m],
                        half_m[m],
                    )
                    sb = _box_distance(
                        balls[k + 1, s, 0],
                        balls[k + 1, s, 1],
                        balls[k + 1, s, 2],
                        rot_m[m],
                        pos_m[m],
                        half_m[m],
                    )
                    sa, sb = max(sa - sph_rad[e, s], 0.0), max(sb - sph_rad[e, s], 0.0)
                    cover[0, s], cover[1, s] = sa, sb
                    low_a, low_b = min(low_a, sa), min(low_b, sb)
                    touching = touching or sa + sb <= 0.0
                ball_whole = np.inf
                if not touching:  # no ball settles otherwise: its motion is not needed
                    if not motion_known[k]:
                        for s in range(count[e]):
                            ball_motion[k, s] = _point_motion(
                                mo, k, k, k + 1, balls[k, s], balls[k + 1, s], sph_coef[e, s], ones
                            )
                        motion_known[k] = True
                    every = True
                    ball_whole = 0.0
                    for s in range(count[e]):
                        if cover[0, s] + cover[1, s] <= ball_motion[k, s]:
                            every = False
                        ball_whole = max(ball_whole, ball_motion[k, s] + sph_rad[e, s] * turns[k])
                    if every:
                        continue
                da, db = max(da, low_a), max(db, low_b)
                moving = min(moving, ball_whole)
                for n in range(k, k + 2):
                    best = 0.0
                    for _round in range(min(_COVER_SLABS, count[e])):
                        # the way from the closest ball's centre to the nearest point of the box
                        s, least = 0, np.inf
                        for t in range(count[e]):
                            if cover[n - k, t] < least:
                                s, least = t, cover[n - k, t]
                        cover[n - k, s] = np.inf
                        dx = balls[n, s, 0] - pos_m[m, 0]
                        dy = balls[n, s, 1] - pos_m[m, 1]
                        dz = balls[n, s, 2] - pos_m[m, 2]
                        wx, wy, wz = 0.0, 0.0, 0.0
                        for axis in range(3):
                            r0, r1, r2 = rot_m[m, 0, axis], rot_m[m, 1, axis], rot_m[m, 2, axis]
                            loc = r0 * dx + r1 * dy + r2 * dz
                            gap = min(max(loc, -half_m[m, axis]), half_m[m, axis]) - loc
                            wx, wy, wz = wx + r0 * gap, wy + r1 * gap, wz + r2 * gap
                        value = _slab(
                            wx, wy, wz, poses[n, e], sup_r, e, pose_obj[m], sup_s, m, True
                        )
                        best = max(best, value)
                    if n == k:
                        da = max(da, best)
                    else:
                        db = max(db, best)
                if da + db > moving:
                    continue
                rows, lows = _grow(rows, lows, found)
                rows[found, 0], rows[found, 1], rows[found, 2] = k, e, m
                lows[found, 0], lows[found, 1], lows[found, 2] = da, db, moving
                found += 1
                if first_only:
                    return rows[:found], lows[:found]
    return rows[:found], lows[:found]


# --- the robot's own pairs ----------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def _self_bound(n, want, ball, low, level, poses, i, j, radius, sup):  # type: ignore[no-untyped-def]  # pragma: no cover
    """A lower bound for elements i and j at sample n, as `_scene_bound`."""
    pi, pj = poses[n, i], poses[n, j]
    if ball[n] < 0.0:
        gap = math.sqrt(
            (pi[0, 3] - pj[0, 3]) ** 2 + (pi[1, 3] - pj[1, 3]) ** 2 + (pi[2, 3] - pj[2, 3]) ** 2
        )
        ball[n] = max(gap - radius[i] - radius[j], 0.0)
    if want == 1:
        return ball[n]
    if level[n] < 2:
        low[n] = max(ball[n], _self_slabs(pi, pj, sup, i, j, False))
        level[n] = 2
    if want >= 3 and level[n] < 3:
        if sup[2][i] >= 0 or sup[2][j] >= 0:
            low[n] = max(low[n], _self_slabs(pi, pj, sup, i, j, True))
        level[n] = 3
    return low[n]


@numba.njit(cache=True, nogil=True)
def self_open_kernel(links, step, robot, half, sup, motion, pairs, first_only):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Rows (K, 2) (segment, pair) that levels 1-3 leave open, with (K, 3) lower bounds at both
    ends and the motion bound, runs of segments first (as `scene_open_kernel`); `pairs`: first
    and second elements (P,), the dofs that change the pair's distance (P, D) as 0/1, and the
    configuration-independent motion per unit step of the element centres and of the whole
    elements (D, P)."""
    link_of, origin, radius, centre_coef, turning, count, sph_local, sph_rad, sph_coef = robot
    rotation, rot_index, after, axis_link, axis_local = motion
    pair_i, pair_j, pair_mask, pair_centre, pair_whole = pairs
    poses, origins, dirs = _pose_all(links, link_of, origin, axis_link, axis_local)
    box_lo, box_hi = _world_boxes(poses, half, radius)
    mo = (step, rotation, rot_index, after, origins, dirs)
    dof = step.shape[1]
    n_samples = links.shape[0]
    n_seg = n_samples - 1
    width = sph_rad.shape[1]
    rows = np.empty((_GROW, 2), dtype=np.int64)
    lows = np.empty((_GROW, 3))
    found = 0
    centre_sum = np.zeros(n_samples)
    whole_sum = np.zeros(n_samples)
    low = np.empty(n_samples)
    level = np.empty(n_samples, dtype=np.int64)
    balls = np.empty((link_of.shape[0], n_samples, width, 3))
    balls_known = np.zeros((link_of.shape[0], n_samples), dtype=np.bool_)
    motion_i = np.empty(width)
    motion_j = np.empty(width)
    cover_low = np.empty((2, width, width))
    ball_low = np.empty(n_samples)
    for p in range(pair_i.shape[0]):
        i, j = pair_i[p], pair_j[p]
        mask = pair_mask[p]
        for k in range(n_seg):
            centre, whole = 0.0, 0.0
            for d in range(dof):
                centre += step[k, d] * pair_centre[d, p]
                whole += step[k, d] * pair_whole[d, p]
            centre_sum[k + 1] = centre_sum[k] + centre
            whole_sum[k + 1] = whole_sum[k] + whole
        ball_low[:] = -1.0
        level[:] = 0
        at = 0  # every segment before sample `at` is certified
        while at < n_seg:
            ahead = at
            d = _self_bound(at, 1, ball_low, low, level, poses, i, j, radius, sup)
            while ahead < n_seg and centre_sum[ahead + 1] - centre_sum[at] < d:
                ahead += 1
            if ahead == at:  # the world boxes' gap, with the motion of any point
                d = _box_gap(box_lo[at, i], box_hi[at, i], box_lo[at, j], box_hi[at, j])
                while ahead < n_seg and whole_sum[ahead + 1] - whole_sum[at] < d:
                    ahead += 1
            if ahead == at:
                d = _self_bound(at, 3, ball_low, low, level, poses, i, j, radius, sup)
                while ahead < n_seg and whole_sum[ahead + 1] - whole_sum[at] < d:
                    ahead += 1
            if ahead > at:
                at = ahead
                continue
            lo, hi = at, at + 1
            at += 1
            settled = False
            moving = whole_sum[hi] - whole_sum[lo]
            box_a = _box_gap(box_lo[lo, i], box_hi[lo, i], box_lo[lo, j], box_hi[lo, j])
            box_b = _box_gap(box_lo[hi, i], box_hi[hi, i], box_lo[hi, j], box_hi[hi, j])
            if box_a + box_b > moving:
                continue
            for want in range(1, 4):
                da = _self_bound(lo, want, ball_low, low, level, poses, i, j, radius, sup)
                db = _self_bound(hi, want, ball_low, low, level, poses, i, j, radius, sup)
                limit = centre_sum[hi] - centre_sum[lo] if want == 1 else moving
                if da + db > limit:
                    settled = True
                    break
            if settled:
                continue
            k = lo
            pia, pib, pja, pjb = poses[k, i], poses[k + 1, i], poses[k, j], poses[k + 1, j]
            turn_i = _turn(step, k, turning, link_of[i], mask)
            turn_j = _turn(step, k, turning, link_of[j], mask)
            dependent = (
                _point_motion(
                    mo, k, k, k + 1, (pia[0, 3], pia[1, 3], pia[2, 3]),
                    (pib[0, 3], pib[1, 3], pib[2, 3]), centre_coef[i], mask,
                )
                + radius[i] * turn_i
                + _point_motion(
                    mo, k, k, k + 1, (pja[0, 3], pja[1, 3], pja[2, 3]),
                    (pjb[0, 3], pjb[1, 3], pjb[2, 3]), centre_coef[j], mask,
                )
                + radius[j] * turn_j
            )  # fmt: skip
            moving = min(moving, dependent)
            if da + db > moving:
                continue
            # level 3: every ball of one cover against every ball of the other
            for side in range(2):
                element = i if side == 0 else j
                for n in range(k, k + 2):
                    if not balls_known[element, n]:
                        frame = links[n, link_of[element]]
                        for s in range(count[element]):
                            bx, by, bz = _transform(
                                frame,
                                sph_local[element, s, 0],
                                sph_local[element, s, 1],
                                sph_local[element, s, 2],
                            )
                            balls[element, n, s, 0] = bx
                            balls[element, n, s, 1] = by
                            balls[element, n, s, 2] = bz
                        balls_known[element, n] = True
            for s in range(count[i]):
                motion_i[s] = _point_motion(
                    mo, k, k, k + 1, balls[i, k, s], balls[i, k + 1, s], sph_coef[i, s], mask
                )
            for t in range(count[j]):
                motion_j[t] = _point_motion(
                    mo, k, k, k + 1, balls[j, k, t], balls[j, k + 1, t], sph_coef[j, t], mask
                )
            every = True
            low_a, low_b = np.inf, np.inf
            for s in range(count[i]):
                for t in range(count[j]):
                    for end in range(2):
                        n = k + end
                        gap = math.sqrt(
                            (balls[i, n, s, 0] - balls[j, n, t, 0]) ** 2
                            + (balls[i, n, s, 1] - balls[j, n, t, 1]) ** 2
                            + (balls[i, n, s, 2] - balls[j, n, t, 2]) ** 2
                        )
                        cover_low[end, s, t] = max(gap - sph_rad[i, s] - sph_rad[j, t], 0.0)
                    if cover_low[0, s, t] + cover_low[1, s, t] <= motion_i[s] + motion_j[t]:
                        every = False
                    low_a, low_b = min(low_a, cover_low[0, s, t]), min(low_b, cover_low[1, s, t])
            if every:
                continue
            widest_i, widest_j = 0.0, 0.0
            for s in range(count[i]):
                widest_i = max(widest_i, motion_i[s] + sph_rad[i, s] * turn_i)
            for t in range(count[j]):
                widest_j = max(widest_j, motion_j[t] + sph_rad[j, t] * turn_j)
            da, db = max(da, low_a), max(db, low_b)
            moving = min(moving, widest_i + widest_j)
            # slabs between the four closest pairs of balls, at each end
            for end in range(2):
                n = k + end
                best = 0.0
                for _round in range(min(4, count[i] * count[j])):
                    pick_s, pick_t, least = 0, 0, np.inf
                    for s in range(count[i]):
                        for t in range(count[j]):
                            if cover_low[end, s, t] < least:
                                least, pick_s, pick_t = cover_low[end, s, t], s, t
                    cover_low[end, pick_s, pick_t] = np.inf
                    value = _slab(
                        balls[j, n, pick_t, 0] - balls[i, n, pick_s, 0],
                        balls[j, n, pick_t, 1] - balls[i, n, pick_s, 1],
                        balls[j, n, pick_t, 2] - balls[i, n, pick_s, 2],
                        poses[n, i], sup, i, poses[n, j], sup, j, True,
                    )  # fmt: skip
                    best = max(best, value)
                if end == 0:
                    da = max(da, best)
                else:
                    db = max(db, best)
            if da + db > moving:
                continue
            rows, lows = _grow(rows, lows, found)
            rows[found, 0], rows[found, 1] = k, p
            lows[found, 0], lows[found, 1], lows[found, 2] = da, db, moving
            found += 1
            if first_only:
                return rows[:found], lows[:found]
    return rows[:found], lows[:found]


# --- states on their own --------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def state_rows_kernel(  # type: ignore[no-untyped-def]  # pragma: no cover
    links, robot, half, sup_r, motion, scene, sup_s, allowed, pairs, element_pad, pair_pad
):
    """The rows of states on their own (no motion) whose lower bounds do not exceed the pads:
    scene rows (K, 3) (state, element, object) with bound ≤ element_pad[state, element], and
    robot-pair rows (K', 2) (state, pair) with bound ≤ pair_pad[state, pair]. Levels: the gap
    between world boxes (each element's, the smaller of its ball's and its local box's, `half`
    (E, 3) about its origin; an object's own), then as in `scene_open_kernel` the element's
    ball, slabs with meshes as boxes, then as hulls. Only these rows need FCL's collision
    test."""
    link_of, origin, radius = robot[0], robot[1], robot[2]
    axis_link, axis_local = motion[3], motion[4]
    rot_m, pos_m, lo_m, hi_m = scene[0], scene[1], scene[3], scene[4]
    pair_i, pair_j = pairs[0], pairs[1]
    poses, _, _ = _pose_all(links, link_of, origin, axis_link, axis_local)
    n_states, n_el, n_obj = links.shape[0], link_of.shape[0], rot_m.shape[0]
    pose_obj = np.empty((n_obj, 3, 4))
    for m in range(n_obj):
        pose_obj[m, :, :3] = rot_m[m]
        pose_obj[m, :, 3] = pos_m[m]
    scene_rows = np.empty((_GROW, 3), dtype=np.int64)
    scene_low = np.empty((_GROW, 3))
    self_rows = np.empty((_GROW, 2), dtype=np.int64)
    self_low = np.empty((_GROW, 3))
    n_scene, n_self = 0, 0
    ball = np.empty(1)
    low = np.empty(1)
    level = np.empty(1, dtype=np.int64)
    boxes_lo, boxes_hi = _world_boxes(poses, half, radius)
    for n in range(n_states):
        box_lo, box_hi = boxes_lo[n], boxes_hi[n]
        for e in range(n_el):
            pad = element_pad[n, e]
            for m in range(n_obj):
                if allowed.shape[0] and allowed[e, m]:
                    continue
                if _box_gap(box_lo[e], box_hi[e], lo_m[m], hi_m[m]) > pad:
                    continue
                ball[0], level[0] = -1.0, 0
                settled = False
                for want in range(1, 4):
                    d = _scene_bound(
                        0, want, ball, low, level, poses[n : n + 1], e, radius, sup_r, pose_obj[m],
                        sup_s, m, scene,
                    )  # fmt: skip
                    if d > pad:
                        settled = True
                        break
                if settled:
                    continue
                scene_rows, scene_low = _grow(scene_rows, scene_low, n_scene)
                scene_rows[n_scene, 0], scene_rows[n_scene, 1], scene_rows[n_scene, 2] = n, e, m
                n_scene += 1
        for p in range(pair_i.shape[0]):
            pad = pair_pad[n, p]
            i, j = pair_i[p], pair_j[p]
            if _box_gap(box_lo[i], box_hi[i], box_lo[j], box_hi[j]) > pad:
                continue
            ball[0], level[0] = -1.0, 0
            settled = False
            for want in range(1, 4):
                d = _self_bound(
                    0, want, ball, low, level, poses[n : n + 1], pair_i[p], pair_j[p], radius, sup_r
                )
                if d > pad:
                    settled = True
                    break
            if settled:
                continue
            self_rows, self_low = _grow(self_rows, self_low, n_self)
            self_rows[n_self, 0], self_rows[n_self, 1] = n, p
            n_self += 1
    return scene_rows[:n_scene], self_rows[:n_self]
