"""Certifying segments in one compiled call: the bound levels, exact distances and conservative
advancement, with no Python per segment, pair or probe; what it cannot settle it leaves.

`validation/certify.py` certifies a chain of samples in stages, each a kernel called from
Python: the levels (`scene_open_kernel`, `self_open_kernel`), then for the pairs they leave
open pieces, exact distances and conservative advancement (`validation/advance.py`). Here the
same argument runs in one call, for a chain whose every pair it can settle:

1. the levels on every segment, as `certify.py` runs them; each open row (segment, pair) comes
   with lower bounds d_a, d_b at its ends and a bound M on how far any point of the pair moves
   relative to the other over the segment;
2. GJK's bound at both ends (`gjk.py`; meshes as their hulls, less `margin`, the exact level's),
   raising d_a and d_b;
3. conservative advancement on what is left (`advance.py`'s argument): the distance is
   M-Lipschitz in the segment fraction, so on a piece [t_a, t_b] with bounds d_a, d_b at its ends
   the pair is apart wherever d_a + d_b > M·(t_b − t_a); else the piece is split inside the part
   neither end covers (within its middle half), the state there posed (`forward_kinematics_kernel`)
   and bounded by GJK, and both halves are tried again.

Every number is a lower bound of a distance or an upper bound of a motion, so an answer of
FREE (the probes taken, ≥ 0) is a certificate of every segment. It answers `UNSETTLED` instead,
and leaves the whole chain to `certify.py`'s stages, at the first of: a bound at an end or probe
not above 0 (a contact is FCL's to find), a piece whose motion falls below `min_pad`, `max_depth`
splits, or a row's probe budget spent. Meshes count as their hulls here, so a pair only their
triangles keep apart (a concave mesh) runs out of probes and goes to the stages, which measure
the triangles (coal). So it never answers where the stages would not certify; it answers sooner.
"""

from __future__ import annotations

import numba
import numpy as np

from trajcache.geometry.collision.compiled.gjk import convex_lower
from trajcache.geometry.collision.compiled.scene_open import scene_open_kernel
from trajcache.geometry.collision.compiled.self_open import self_open_kernel
from trajcache.geometry.model.kernels import BORROWED, forward_kinematics_kernel

UNSETTLED = -1
_STACK = 64  # pieces waiting, at most: depth-first, two per split


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _pose(links, n, link, origin, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """out (4 × 4) = links[n, link] @ origin (4 × 4): an element's world pose."""
    for r in range(3):
        for c in range(4):
            out[r, c] = (
                links[n, link, r, 0] * origin[0, c]
                + links[n, link, r, 1] * origin[1, c]
                + links[n, link, r, 2] * origin[2, c]
                + links[n, link, r, 3] * origin[3, c]
            )
    out[3, 0], out[3, 1], out[3, 2], out[3, 3] = 0.0, 0.0, 0.0, 1.0


@numba.njit(cache=True, nogil=True, **BORROWED)
def _bound(links, n, a, b, other, bodies, margin, need, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """GJK's lower bound, less `margin`, between element a and object b (`other`) or element
    b at links[n], meshes as their hulls; it stops once above `need`. bodies: element links
    and origins, the robot's and scene's support tables, the objects' poses."""
    link_of, origin, sup_r, sup_s, poses_m = bodies
    pose_a, pose_b, simplex = work[0], work[1], work[2]
    _pose(links, n, link_of[a], origin[a], pose_a)
    if other:
        return convex_lower(pose_a, sup_r, a, poses_m[b], sup_s, b, need, simplex) - margin
    _pose(links, n, link_of[b], origin[b], pose_b)
    return convex_lower(pose_a, sup_r, a, pose_b, sup_r, b, need, simplex) - margin


@numba.njit(cache=True, nogil=True, **BORROWED)
def _advance(seg, a, b, other, d_a, d_b, motion, chain, bodies, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The probes advancement took to certify the pair (a, b; `other`: b is an object) on
    segment `seg` from bounds d_a, d_b at its ends and motion bound `motion` (module doc), or
    −1 once a piece is too short, too deep or the probes run out."""
    samples, delta, fk, probe, limits = chain
    min_pad, max_depth, margin, budget = limits[0], limits[1], limits[2], limits[3]
    stack, q = work[3], work[4]
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3], stack[0, 4] = 0.0, 1.0, d_a, d_b, 0.0
    top, probes = 1, 0
    while top > 0:
        top -= 1
        t0, t1, d0, d1 = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        depth = stack[top, 4]
        reach = motion * (t1 - t0)
        if d0 + d1 > reach:
            continue
        if reach < min_pad or depth >= max_depth or probes >= budget or top + 2 > len(stack):
            return -1
        frac = min(max((d0 / reach + 1.0 - d1 / reach) / 2.0, 0.25), 0.75)
        mid = t0 + (t1 - t0) * frac
        need = max(motion * (mid - t0) - d0, motion * (t1 - mid) - d1)
        for j in range(q.shape[1]):
            q[0, j] = samples[seg, j] + mid * delta[seg, j]
        forward_kinematics_kernel(
            q, fk[0], fk[1], fk[2], fk[3], fk[4], fk[5], fk[6], fk[7], fk[8], fk[9], fk[10], probe
        )
        probes += 1
        d_m = _bound(probe, 0, a, b, other, bodies, margin, need, work)
        if d_m <= 0.0:
            return -1
        stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = t0, mid, d0, d_m
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = (
            mid,
            t1,
            d_m,
            d1,
        )
        stack[top, 4] = stack[top + 1, 4] = depth + 1.0
        top += 2
    return probes


@numba.njit(cache=True, nogil=True, **BORROWED)
def _ends(rows, lows, other, pairs, links, chain, bodies, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """GJK's bounds at both ends of the open rows (scene rows with `other`, else robot pairs)
    raise the levels' in lows[:, :2]; False as soon as one is not positive (FCL's to test)."""
    margin = chain[4][2]
    for k in range(rows.shape[0]):
        a, b = (rows[k, 1], rows[k, 2]) if other else (pairs[0][rows[k, 1]], pairs[1][rows[k, 1]])
        for end in range(2):
            bound = _bound(links, rows[k, 0] + end, a, b, other, bodies, margin, lows[k, 2], work)
            lows[k, end] = max(lows[k, end], bound)
            if lows[k, end] <= 0.0:
                return False
    return True


@numba.njit(cache=True, nogil=True, **BORROWED)
def _advance_rows(rows, lows, other, pairs, chain, bodies, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The probes advancement took to certify every open row (bounds at both ends and motion
    in `lows`), or −1 at the first it could not."""
    probes = 0
    for k in range(rows.shape[0]):
        if lows[k, 0] + lows[k, 1] > lows[k, 2]:
            continue
        a, b = (rows[k, 1], rows[k, 2]) if other else (pairs[0][rows[k, 1]], pairs[1][rows[k, 1]])
        taken = _advance(
            rows[k, 0], a, b, other, lows[k, 0], lows[k, 1], lows[k, 2], chain, bodies, work
        )
        if taken < 0:
            return -1
        probes += taken
    return probes


@numba.njit(cache=True, nogil=True)
def settle_kernel(samples, delta, step, fk, levels, pairs, poses_m, limits):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The advancement probes taken (≥ 0) when every segment between consecutive `samples`
    (N, D) is certified against the scene and for every robot pair of `pairs` (module doc),
    else UNSETTLED (−1).

    delta (N − 1, D): the segments' differences (a base heading the short way); step: their
    `MotionBounds.steps`; fk: `kinematics.fk_tables`; levels: robot, half, sup_r, motion, scene,
    sup_s, allowed, as `scene_open_kernel` takes them; pairs: as `self_open_kernel` does;
    poses_m (M, 4, 4): the objects'; limits: min_pad, max_depth, the exact level's margin, and
    the probes one row may take.
    """
    robot, half, sup_r, motion, scene, sup_s, allowed = levels
    links = np.empty((samples.shape[0], fk[2].max() + 1 if fk[2].shape[0] else 1, 4, 4))
    forward_kinematics_kernel(
        samples, fk[0], fk[1], fk[2], fk[3], fk[4], fk[5], fk[6], fk[7], fk[8], fk[9], fk[10],
        links,
    )  # fmt: skip
    work = (
        np.empty((4, 4)), np.empty((4, 4)), np.empty((4, 3)), np.empty((_STACK, 5)),
        np.empty((1, samples.shape[1])),
    )  # fmt: skip
    chain = (samples, delta, fk, np.empty((1, links.shape[1], 4, 4)), limits)
    bodies = (robot[0], robot[1], sup_r, sup_s, poses_m)
    rows, lows = scene_open_kernel(
        links, step, robot, half, sup_r, motion, scene, sup_s, allowed, False
    )
    if not _ends(rows, lows, True, pairs, links, chain, bodies, work):
        return UNSETTLED
    pair_rows, pair_lows = np.empty((0, 2), dtype=np.int64), np.empty((0, 3))
    if pairs[0].shape[0]:
        pair_rows, pair_lows = self_open_kernel(
            links, step, robot, half, sup_r, motion, pairs, False
        )
        if not _ends(pair_rows, pair_lows, False, pairs, links, chain, bodies, work):
            return UNSETTLED
    scene_probes = _advance_rows(rows, lows, True, pairs, chain, bodies, work)
    if scene_probes < 0:
        return UNSETTLED
    pair_probes = _advance_rows(pair_rows, pair_lows, False, pairs, chain, bodies, work)
    return UNSETTLED if pair_probes < 0 else scene_probes + pair_probes
