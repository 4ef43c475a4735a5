"""States on their own, compiled: the rows of single states that only FCL can settle."""

from __future__ import annotations

import numba
import numpy as np

from trajcache.geometry.collision.compiled.primitives import (
    GROW,
    box_gap,
    grow,
    object_poses,
    pose_all,
    world_boxes,
)
from trajcache.geometry.collision.compiled.scene_open import scene_bound
from trajcache.geometry.collision.compiled.self_open import self_bound


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
    poses, _, _ = pose_all(links, link_of, origin, axis_link, axis_local)
    n_states, n_el, n_obj = links.shape[0], link_of.shape[0], rot_m.shape[0]
    pose_obj = object_poses(rot_m, pos_m)
    scene_rows = np.empty((GROW, 3), dtype=np.int64)
    scene_low = np.empty((GROW, 3))
    self_rows = np.empty((GROW, 2), dtype=np.int64)
    self_low = np.empty((GROW, 3))
    n_scene, n_self = 0, 0
    ball = np.empty(1)
    low = np.empty(1)
    level = np.empty(1, dtype=np.int64)
    boxes_lo, boxes_hi = world_boxes(poses, half, radius)
    for n in range(n_states):
        box_lo, box_hi = boxes_lo[n], boxes_hi[n]
        for e in range(n_el):
            pad = element_pad[n, e]
            for m in range(n_obj):
                if allowed.shape[0] and allowed[e, m]:
                    continue
                if box_gap(box_lo[e], box_hi[e], lo_m[m], hi_m[m]) > pad:
                    continue
                ball[0], level[0] = -1.0, 0
                settled = False
                for want in range(1, 4):
                    d = scene_bound(
                        0, want, ball, low, level, poses[n : n + 1], e, radius, sup_r, pose_obj[m],
                        sup_s, m, scene,
                    )  # fmt: skip
                    if d > pad:
                        settled = True
                        break
                if settled:
                    continue
                scene_rows, scene_low = grow(scene_rows, scene_low, n_scene)
                scene_rows[n_scene, 0], scene_rows[n_scene, 1], scene_rows[n_scene, 2] = n, e, m
                n_scene += 1
        for p in range(pair_i.shape[0]):
            pad = pair_pad[n, p]
            i, j = pair_i[p], pair_j[p]
            if box_gap(box_lo[i], box_hi[i], box_lo[j], box_hi[j]) > pad:
                continue
            ball[0], level[0] = -1.0, 0
            settled = False
            for want in range(1, 4):
                d = self_bound(
                    0, want, ball, low, level, poses[n : n + 1], pair_i[p], pair_j[p], radius, sup_r
                )
                if d > pad:
                    settled = True
                    break
            if settled:
                continue
            self_rows, self_low = grow(self_rows, self_low, n_self)
            self_rows[n_self, 0], self_rows[n_self, 1] = n, p
            n_self += 1
    return scene_rows[:n_scene], self_rows[:n_self]
