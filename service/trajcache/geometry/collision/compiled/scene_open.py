"""The scene levels compiled: which (segment, element, object) rows levels 1-3 leave open."""

from __future__ import annotations

import numba
import numpy as np

from trajcache.geometry.collision.compiled.primitives import (
    GROW,
    box_distance,
    box_distance_at,
    box_gap_at,
    cover_motion,
    object_poses,
    place_cover,
    point_motion,
    pose_all,
    turn,
    world_boxes,
)
from trajcache.geometry.collision.compiled.slabs import scene_slabs, slab_bound
from trajcache.geometry.model.kernels import BORROWED

_COVER_SLABS = 4  # slabs along the ways of the closest cover balls, per end


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _ball_bound(n, ball, poses, e, radius, rot_m, pos_m, half_m, m):  # type: ignore[no-untyped-def]  # pragma: no cover
    """`scene_bound`'s level 1 (the element's ball against object m's box at sample n), with
    arrays and indices only: it runs for every (sample, element, object) the advancement
    visits, where passing the support tables' tuples would cost more than the bound."""
    if ball[n] < 0.0:
        gap = box_distance_at(
            poses[n, e, 0, 3], poses[n, e, 1, 3], poses[n, e, 2, 3], rot_m, pos_m, half_m, m
        )
        ball[n] = max(gap - radius[e], 0.0)
    return ball[n]


@numba.njit(cache=True, nogil=True, **BORROWED)
def scene_bound(n, want, ball, low, level, poses, e, radius, sup_r, pose_m, sup_s, m, scene):  # type: ignore[no-untyped-def]  # pragma: no cover
    """A lower bound for element e and object m at sample n: with `want` 1, of the element's
    ball (whose points move as its centre does); with 2, of the element itself, by slabs with
    meshes as boxes; with 3, by slabs with meshes as hulls. Cached in ball[n] (−1: not yet) and
    low[n], level[n] (0: not yet)."""
    pose = poses[n, e]
    half_m = scene[2]
    _ball_bound(n, ball, poses, e, radius, scene[0], scene[1], half_m, m)
    if want == 1:
        return ball[n]
    if level[n] < 2:
        low[n] = max(ball[n], scene_slabs(pose, sup_r, e, pose_m, sup_s, m, half_m[m], False))
        level[n] = 2
    if want >= 3 and level[n] < 3:
        if sup_r[2][e] >= 0 or sup_s[2][m] >= 0:
            low[n] = max(low[n], scene_slabs(pose, sup_r, e, pose_m, sup_s, m, half_m[m], True))
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

    It allocates what the elements share and its output, and leaves each element's rows to
    `_element_rows`, which allocates nothing: compiled without reference counting, it works
    on borrowed arrays alone (`model/kernels.BORROWED`), where counting the references of the
    views and tuples it passes around cost as much as the bounds themselves.
    """
    link_of, origin, radius = robot[0], robot[1], robot[2]
    axis_link, axis_local = motion[3], motion[4]
    rot_m, pos_m = scene[0], scene[1]
    poses, origins, dirs = pose_all(links, link_of, origin, axis_link, axis_local)
    box_lo, box_hi = world_boxes(poses, half, radius)
    n_el, n_obj, dof = link_of.shape[0], rot_m.shape[0], step.shape[1]
    n_samples = links.shape[0]
    n_seg = max(n_samples - 1, 1)
    width = robot[7].shape[1]
    placed = (poses, origins, dirs, box_lo, box_hi, object_poses(rot_m, pos_m), np.ones(dof))
    work = _work(n_samples, n_seg, width)
    most = n_obj * n_seg  # rows one element can leave open
    rows = np.empty((GROW, 3), dtype=np.int64)
    lows = np.empty((GROW, 3))
    found = 0
    for e in range(n_el):
        if found + most > rows.shape[0]:
            size = max(2 * rows.shape[0], found + most)
            more_rows = np.empty((size, 3), dtype=np.int64)
            more_lows = np.empty((size, 3))
            more_rows[:found] = rows[:found]
            more_lows[:found] = lows[:found]
            rows, lows = more_rows, more_lows
        found = _element_rows(
            e, links, step, robot, sup_r, motion, scene, sup_s, allowed, first_only, placed,
            work, rows, lows, found,
        )  # fmt: skip
        if first_only and found:
            break
    return rows[:found], lows[:found]


@numba.njit(cache=True, nogil=True)
def _work(n_samples, n_seg, width):  # type: ignore[no-untyped-def]  # pragma: no cover
    """`_element_rows`' buffers, which each element fills anew."""
    return (
        np.zeros(n_samples),  # centre_sum
        np.zeros(n_samples),  # whole_sum
        np.empty(n_seg),  # turns
        np.empty(n_seg),  # dependent
        np.empty(n_samples),  # low
        np.empty(n_samples, dtype=np.int64),  # level
        np.empty((n_samples, width, 3)),  # balls
        np.empty(n_samples, dtype=np.bool_),  # balls_known
        np.empty((n_seg, width)),  # ball_motion
        np.empty((2, width)),  # cover
        np.empty(n_seg, dtype=np.bool_),  # motion_known
        np.empty(n_samples),  # ball_low
        np.empty((2, 3)),  # near
    )


@numba.njit(cache=True, nogil=True, **BORROWED)
def _element_rows(  # type: ignore[no-untyped-def]  # pragma: no cover
    e,
    links,
    step,
    robot,
    sup_r,
    motion,
    scene,
    sup_s,
    allowed,
    first_only,
    placed,
    work,
    rows,
    lows,
    found,
):
    """`scene_open_kernel`'s rows of element e, written from rows[found] on (room is left for
    every object on every segment); the new count."""
    link_of, _origin, radius, centre_coef, turning, count, sph_local, sph_rad, sph_coef = robot
    rotation, rot_index, after, _axis_link, _axis_local = motion
    rot_m, pos_m, half_m, lo_m, hi_m = scene
    poses, origins, dirs, box_lo, box_hi, pose_obj, ones = placed
    centre_sum, whole_sum, turns, dependent, low, level, balls = work[:7]
    balls_known, ball_motion, cover, motion_known, ball_low, near = work[7:]
    mo = (step, rotation, rot_index, after, origins, dirs)
    n_obj = rot_m.shape[0]
    n_seg = links.shape[0] - 1
    link = link_of[e]
    widest = _motion_sums(
        step, centre_coef[e], radius[e], turning, link, ones, centre_sum, whole_sum, turns
    )
    # every point of the element stays within radius + widest of its origin at a sample
    _reach(poses, e, radius[e] + widest, near)
    dependent[:] = -1.0
    balls_known[:] = False
    motion_known[:] = False
    for m in range(n_obj):
        if allowed.shape[0] and allowed[e, m]:
            continue
        if _out_of_reach(lo_m, hi_m, m, near):
            continue
        ball_low[:] = -1.0
        level[:] = 0
        at = 0  # every segment before sample `at` is certified
        while at < n_seg:
            # ahead from `at` while the summed motion stays below the bound there
            ahead = at
            d = _ball_bound(at, ball_low, poses, e, radius, rot_m, pos_m, half_m, m)
            while ahead < n_seg and centre_sum[ahead + 1] - centre_sum[at] < d:
                ahead += 1
            if ahead == at:  # the world boxes' gap, with the motion of any point
                d = box_gap_at(box_lo, box_hi, at, e, lo_m, hi_m, m)
                while ahead < n_seg and whole_sum[ahead + 1] - whole_sum[at] < d:
                    ahead += 1
            if ahead == at:
                d = scene_bound(
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
            box_a = box_gap_at(box_lo, box_hi, lo, e, lo_m, hi_m, m)
            box_b = box_gap_at(box_lo, box_hi, hi, e, lo_m, hi_m, m)
            if box_a + box_b > moving:
                continue
            da = _ball_bound(lo, ball_low, poses, e, radius, rot_m, pos_m, half_m, m)
            db = _ball_bound(hi, ball_low, poses, e, radius, rot_m, pos_m, half_m, m)
            settled = da + db > centre_sum[hi] - centre_sum[lo]
            for want in range(2, 4):
                if settled:
                    break
                da = scene_bound(
                    lo, want, ball_low, low, level, poses, e, radius, sup_r, pose_obj[m], sup_s,
                    m, scene,
                )  # fmt: skip
                db = scene_bound(
                    hi, want, ball_low, low, level, poses, e, radius, sup_r, pose_obj[m], sup_s,
                    m, scene,
                )  # fmt: skip
                settled = da + db > moving
            if settled:
                continue
            k = lo
            if dependent[k] < 0.0:
                pa, pb = poses[k, e], poses[k + 1, e]
                dependent[k] = min(
                    moving,
                    point_motion(
                        mo, k, k, k + 1, (pa[0, 3], pa[1, 3], pa[2, 3]),
                        (pb[0, 3], pb[1, 3], pb[2, 3]), centre_coef[e], ones,
                    )
                    + radius[e] * turns[k],
                )  # fmt: skip
            moving = dependent[k]
            if da + db > moving:
                continue
            # an end in contact, or too close to tell: FCL's collision test decides it before
            # anything finer is worth computing (`certify._sample_collision`)
            in_contact = da <= 0.0 or db <= 0.0
            if not in_contact:  # level 3: the sphere cover
                place_cover(links, link, sph_local[e], count[e], k, balls, balls_known)
                low_a, low_b, touching = _cover_gaps(
                    balls, k, count[e], sph_rad[e], rot_m[m], pos_m[m], half_m[m], cover
                )
                ball_whole = np.inf
                if not touching:  # no ball settles otherwise: its motion is not needed
                    if not motion_known[k]:
                        cover_motion(mo, k, balls, sph_coef[e], count[e], ones, ball_motion[k])
                        motion_known[k] = True
                    every, ball_whole = _cover_settles(
                        cover, ball_motion[k], count[e], sph_rad[e], turns[k]
                    )
                    if every:
                        continue
                da, db = max(da, low_a), max(db, low_b)
                moving = min(moving, ball_whole)
                best_a, best_b = _cover_slabs(
                    balls, k, count[e], cover, poses, e, sup_r, pose_obj[m], sup_s, m, scene
                )
                da, db = max(da, best_a), max(db, best_b)
                if da + db > moving:
                    continue
            rows[found, 0], rows[found, 1], rows[found, 2] = k, e, m
            lows[found, 0], lows[found, 1], lows[found, 2] = da, db, moving
            found += 1
            if first_only:
                return found
    return found


@numba.njit(cache=True, nogil=True, **BORROWED)
def _motion_sums(step, coef, radius, turning, link, ones, centre_sum, whole_sum, turns):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Running sums over the segments of the configuration-independent motion of an element's
    centre and of the whole element (turns[k]: the turn of the dofs that move it); returns the
    widest whole motion over one segment."""
    widest = 0.0
    for k in range(step.shape[0]):
        centre = 0.0
        for d in range(step.shape[1]):
            centre += step[k, d] * coef[d]
        turns[k] = turn(step, k, turning, link, ones)
        whole = centre + radius * turns[k]
        centre_sum[k + 1] = centre_sum[k] + centre
        whole_sum[k + 1] = whole_sum[k] + whole
        widest = max(widest, whole)
    return widest


@numba.njit(cache=True, nogil=True, **BORROWED)
def _reach(poses, e, reach, near):  # type: ignore[no-untyped-def]  # pragma: no cover
    """near[0], near[1]: the box (low, high) of element e's origins at every sample, grown by
    `reach`."""
    for a in range(3):
        near[0, a], near[1, a] = np.inf, -np.inf
    for n in range(poses.shape[0]):
        for a in range(3):
            near[0, a] = min(near[0, a], poses[n, e, a, 3])
            near[1, a] = max(near[1, a], poses[n, e, a, 3])
    for a in range(3):
        near[0, a], near[1, a] = near[0, a] - reach, near[1, a] + reach


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _out_of_reach(lo_m, hi_m, m, near):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether object m's box lies wholly outside the box `near` (low, high)."""
    apart = False
    for a in range(3):
        apart = apart or lo_m[m, a] > near[1, a] or hi_m[m, a] < near[0, a]
    return apart


@numba.njit(cache=True, nogil=True, **BORROWED)
def _cover_gaps(balls, k, count, rad, rot, pos, half, cover):  # type: ignore[no-untyped-def]  # pragma: no cover
    """cover[end, s]: the gap between cover ball s and the object's box at sample k + end; the
    least at each end, and whether a ball touches the box at both."""
    low_a, low_b, touching = np.inf, np.inf, False
    for s in range(count):
        sa = box_distance(balls[k, s, 0], balls[k, s, 1], balls[k, s, 2], rot, pos, half)
        sb = box_distance(
            balls[k + 1, s, 0], balls[k + 1, s, 1], balls[k + 1, s, 2], rot, pos, half
        )
        sa, sb = max(sa - rad[s], 0.0), max(sb - rad[s], 0.0)
        cover[0, s], cover[1, s] = sa, sb
        low_a, low_b = min(low_a, sa), min(low_b, sb)
        touching = touching or sa + sb <= 0.0
    return low_a, low_b, touching


@numba.njit(cache=True, nogil=True, **BORROWED)
def _cover_settles(cover, motion, count, rad, turned):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether every cover ball is certified with the motion of its centre, and the motion of
    the whole cover (its widest ball's, grown by its radius times the turn)."""
    every = True
    ball_whole = 0.0
    for s in range(count):
        if cover[0, s] + cover[1, s] <= motion[s]:
            every = False
        ball_whole = max(ball_whole, motion[s] + rad[s] * turned)
    return every, ball_whole


@numba.njit(cache=True, nogil=True, **BORROWED)
def _cover_slabs(balls, k, count, cover, poses, e, sup_r, pose_m, sup_s, m, scene):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The best slab at samples k and k + 1 along the ways from the closest cover balls' centres
    to the nearest points of the object's box (consumes `cover`)."""
    rot_m, pos_m, half_m = scene[0], scene[1], scene[2]
    best_a, best_b = 0.0, 0.0
    for n in range(k, k + 2):
        best = 0.0
        for _round in range(min(_COVER_SLABS, count)):
            s, least = 0, np.inf
            for t in range(count):
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
            value = slab_bound(wx, wy, wz, poses[n, e], sup_r, e, pose_m, sup_s, m, True)
            best = max(best, value)
        if n == k:
            best_a = best
        else:
            best_b = best
    return best_a, best_b
