"""The robot's own pairs compiled: which (segment, pair) rows levels 1-3 leave open."""

from __future__ import annotations

import math

import numba
import numpy as np

from trajcache.geometry.collision.compiled.primitives import (
    GROW,
    box_gap_pair,
    cover_motion,
    grow,
    place_cover,
    point_motion,
    pose_all,
    turn,
    world_boxes,
)
from trajcache.geometry.collision.compiled.slabs import self_slabs, slab_bound
from trajcache.geometry.model.kernels import BORROWED


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _ball_bound(n, ball, poses, i, j, radius):  # type: ignore[no-untyped-def]  # pragma: no cover
    """`self_bound`'s level 1 (the elements' balls) at sample n, by index: it runs for every
    (sample, pair) the advancement visits, where the support tuple would cost more."""
    if ball[n] < 0.0:
        gap = math.sqrt(
            (poses[n, i, 0, 3] - poses[n, j, 0, 3]) ** 2
            + (poses[n, i, 1, 3] - poses[n, j, 1, 3]) ** 2
            + (poses[n, i, 2, 3] - poses[n, j, 2, 3]) ** 2
        )
        ball[n] = max(gap - radius[i] - radius[j], 0.0)
    return ball[n]


@numba.njit(cache=True, nogil=True, **BORROWED)
def self_bound(n, want, ball, low, level, poses, i, j, radius, sup):  # type: ignore[no-untyped-def]  # pragma: no cover
    """A lower bound for elements i and j at sample n, as `scene_bound`."""
    pi, pj = poses[n, i], poses[n, j]
    _ball_bound(n, ball, poses, i, j, radius)
    if want == 1:
        return ball[n]
    if level[n] < 2:
        low[n] = max(ball[n], self_slabs(pi, pj, sup, i, j, False))
        level[n] = 2
    if want >= 3 and level[n] < 3:
        if sup[2][i] >= 0 or sup[2][j] >= 0:
            low[n] = max(low[n], self_slabs(pi, pj, sup, i, j, True))
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
    poses, origins, dirs = pose_all(links, link_of, origin, axis_link, axis_local)
    box_lo, box_hi = world_boxes(poses, half, radius)
    mo = (step, rotation, rot_index, after, origins, dirs)
    n_samples = links.shape[0]
    n_seg = n_samples - 1
    width = sph_rad.shape[1]
    rows = np.empty((GROW, 2), dtype=np.int64)
    lows = np.empty((GROW, 3))
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
        _motion_sums(step, pair_centre, pair_whole, p, centre_sum, whole_sum)
        ball_low[:] = -1.0
        level[:] = 0
        at = 0  # every segment before sample `at` is certified
        while at < n_seg:
            ahead = at
            d = _ball_bound(at, ball_low, poses, i, j, radius)
            while ahead < n_seg and centre_sum[ahead + 1] - centre_sum[at] < d:
                ahead += 1
            if ahead == at:  # the world boxes' gap, with the motion of any point
                d = box_gap_pair(box_lo, box_hi, at, i, j)
                while ahead < n_seg and whole_sum[ahead + 1] - whole_sum[at] < d:
                    ahead += 1
            if ahead == at:
                d = self_bound(at, 3, ball_low, low, level, poses, i, j, radius, sup)
                while ahead < n_seg and whole_sum[ahead + 1] - whole_sum[at] < d:
                    ahead += 1
            if ahead > at:
                at = ahead
                continue
            lo, hi = at, at + 1
            at += 1
            settled = False
            moving = whole_sum[hi] - whole_sum[lo]
            box_a = box_gap_pair(box_lo, box_hi, lo, i, j)
            box_b = box_gap_pair(box_lo, box_hi, hi, i, j)
            if box_a + box_b > moving:
                continue
            da = _ball_bound(lo, ball_low, poses, i, j, radius)
            db = _ball_bound(hi, ball_low, poses, i, j, radius)
            settled = da + db > centre_sum[hi] - centre_sum[lo]
            for want in range(2, 4):
                if settled:
                    break
                da = self_bound(lo, want, ball_low, low, level, poses, i, j, radius, sup)
                db = self_bound(hi, want, ball_low, low, level, poses, i, j, radius, sup)
                settled = da + db > moving
            if settled:
                continue
            k = lo
            pia, pib, pja, pjb = poses[k, i], poses[k + 1, i], poses[k, j], poses[k + 1, j]
            turn_i = turn(step, k, turning, link_of[i], mask)
            turn_j = turn(step, k, turning, link_of[j], mask)
            dependent = (
                point_motion(
                    mo, k, k, k + 1, (pia[0, 3], pia[1, 3], pia[2, 3]),
                    (pib[0, 3], pib[1, 3], pib[2, 3]), centre_coef[i], mask,
                )
                + radius[i] * turn_i
                + point_motion(
                    mo, k, k, k + 1, (pja[0, 3], pja[1, 3], pja[2, 3]),
                    (pjb[0, 3], pjb[1, 3], pjb[2, 3]), centre_coef[j], mask,
                )
                + radius[j] * turn_j
            )  # fmt: skip
            moving = min(moving, dependent)
            if da + db > moving:
                continue
            # level 3: every ball of one cover against every ball of the other
            bi, bj = balls[i], balls[j]
            place_cover(links, link_of[i], sph_local[i], count[i], k, bi, balls_known[i])
            place_cover(links, link_of[j], sph_local[j], count[j], k, bj, balls_known[j])
            cover_motion(mo, k, bi, sph_coef[i], count[i], mask, motion_i)
            cover_motion(mo, k, bj, sph_coef[j], count[j], mask, motion_j)
            every, low_a, low_b = _cover_gaps(
                bi, bj, k, count[i], count[j], sph_rad[i], sph_rad[j], motion_i, motion_j, cover_low
            )
            if every:
                continue
            widest_i, widest_j = 0.0, 0.0
            for s in range(count[i]):
                widest_i = max(widest_i, motion_i[s] + sph_rad[i, s] * turn_i)
            for t in range(count[j]):
                widest_j = max(widest_j, motion_j[t] + sph_rad[j, t] * turn_j)
            da, db = max(da, low_a), max(db, low_b)
            moving = min(moving, widest_i + widest_j)
            best_a, best_b = _cover_slabs(
                bi, bj, k, count[i], count[j], cover_low, poses, i, j, sup
            )
            da, db = max(da, best_a), max(db, best_b)
            if da + db > moving:
                continue
            rows, lows = grow(rows, lows, found)
            rows[found, 0], rows[found, 1] = k, p
            lows[found, 0], lows[found, 1], lows[found, 2] = da, db, moving
            found += 1
            if first_only:
                return rows[:found], lows[:found]
    return rows[:found], lows[:found]


@numba.njit(cache=True, nogil=True, **BORROWED)
def _motion_sums(step, pair_centre, pair_whole, p, centre_sum, whole_sum):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Running sums over the segments of the configuration-independent motion of pair p's
    element centres and of its whole elements."""
    for k in range(step.shape[0]):
        centre, whole = 0.0, 0.0
        for d in range(step.shape[1]):
            centre += step[k, d] * pair_centre[d, p]
            whole += step[k, d] * pair_whole[d, p]
        centre_sum[k + 1] = centre_sum[k] + centre
        whole_sum[k + 1] = whole_sum[k] + whole


@numba.njit(cache=True, nogil=True, **BORROWED)
def _cover_gaps(bi, bj, k, count_i, count_j, rad_i, rad_j, motion_i, motion_j, cover_low):  # type: ignore[no-untyped-def]  # pragma: no cover
    """cover_low[end, s, t]: the gap between ball s of one cover and ball t of the other at
    sample k + end; whether every pair of balls is certified with their centres' motion, and
    the least gap at each end."""
    every = True
    low_a, low_b = np.inf, np.inf
    for s in range(count_i):
        for t in range(count_j):
            for end in range(2):
                n = k + end
                gap = math.sqrt(
                    (bi[n, s, 0] - bj[n, t, 0]) ** 2
                    + (bi[n, s, 1] - bj[n, t, 1]) ** 2
                    + (bi[n, s, 2] - bj[n, t, 2]) ** 2
                )
                cover_low[end, s, t] = max(gap - rad_i[s] - rad_j[t], 0.0)
            if cover_low[0, s, t] + cover_low[1, s, t] <= motion_i[s] + motion_j[t]:
                every = False
            low_a, low_b = min(low_a, cover_low[0, s, t]), min(low_b, cover_low[1, s, t])
    return every, low_a, low_b


@numba.njit(cache=True, nogil=True, **BORROWED)
def _cover_slabs(bi, bj, k, count_i, count_j, cover_low, poses, i, j, sup):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The best slab at samples k and k + 1 between the four closest pairs of balls there
    (consumes `cover_low`)."""
    best_a, best_b = 0.0, 0.0
    for end in range(2):
        n = k + end
        best = 0.0
        for _round in range(min(4, count_i * count_j)):
            pick_s, pick_t, least = 0, 0, np.inf
            for s in range(count_i):
                for t in range(count_j):
                    if cover_low[end, s, t] < least:
                        least, pick_s, pick_t = cover_low[end, s, t], s, t
            cover_low[end, pick_s, pick_t] = np.inf
            value = slab_bound(
                bj[n, pick_t, 0] - bi[n, pick_s, 0],
                bj[n, pick_t, 1] - bi[n, pick_s, 1],
                bj[n, pick_t, 2] - bi[n, pick_s, 2],
                poses[n, i], sup, i, poses[n, j], sup, j, True,
            )  # fmt: skip
            best = max(best, value)
        if end == 0:
            best_a = best
        else:
            best_b = best
    return best_a, best_b
