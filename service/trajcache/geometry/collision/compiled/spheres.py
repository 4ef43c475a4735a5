"""One robot state against the scene and itself on sphere covers, compiled: free, open or
colliding, for planners whose whole loop is compiled (`planning/compiled/`).

The robot is its elements' sphere covers (`model/support.sphere_cover`: the union of an
element's balls contains the element, surface and solid), behind one bounding ball per element.
A scene object is its exact primitive (box, sphere, cylinder, capsule) or, for a mesh, its
oriented bounding box. With sd(p) the signed distance from a point p to the object (negative
inside):

- FREE for an (element, object) row when the element's ball, or each of its cover balls
  (c, r), has sd(c) > r: the ball, which contains (that part of) the element, misses the
  object. A self-collision pair is free when its elements' balls, or every pair of their cover
  balls, are apart. A state is FREE when every row and pair is: the proof is the cover's.
- COLLIDING when a cover ball's centre lies deeper inside a (non-mesh) object than the centre's
  distance e(c) to the element's surface (`sphere_tables.surface_reach`): the surface point
  nearest c is within e(c) of c, so it lies inside the object, and the element's surface meets
  the object's solid, which is a collision for FCL too. Nothing else is called colliding.
- OPEN otherwise: the covers neither prove the state free nor colliding, and the exact check
  (FCL, in Python) decides. Self-collision pairs are never proven colliding here.

`sphere_state` returns 0 (FREE), 1 (OPEN) or 2 (COLLIDING).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from trajcache.geometry.model.kernels import forward_kinematics_kernel

FREE, OPEN, COLLIDING = 0, 1, 2
BOX, SPHERE, CYLINDER, CAPSULE, MESH = 0, 1, 2, 3, 4


@numba.njit(cache=True, nogil=True)
def signed_distance(kind, rot, pos, size, x, y, z):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Signed distance from world point (x, y, z) to an object (negative inside); a mesh is
    its oriented bounding box (`size` = half extents), which contains it."""
    dx, dy, dz = x - pos[0], y - pos[1], z - pos[2]
    px = rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0] * dz
    py = rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1] * dz
    pz = rot[0, 2] * dx + rot[1, 2] * dy + rot[2, 2] * dz
    if kind == BOX or kind == MESH:  # noqa: SIM109  (compiled: plain comparisons)
        qx, qy, qz = abs(px) - size[0], abs(py) - size[1], abs(pz) - size[2]
        out = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2 + max(qz, 0.0) ** 2)
        return out + min(max(qx, max(qy, qz)), 0.0)
    if kind == SPHERE:
        return math.sqrt(px * px + py * py + pz * pz) - size[0]
    if kind == CYLINDER:
        dr = math.sqrt(px * px + py * py) - size[0]
        dh = abs(pz) - size[1]
        return math.sqrt(max(dr, 0.0) ** 2 + max(dh, 0.0) ** 2) + min(max(dr, dh), 0.0)
    # capsule: a segment on z of half length size[1], grown by size[0]
    cz = min(max(pz, -size[1]), size[1])
    return math.sqrt(px * px + py * py + (pz - cz) ** 2) - size[0]


@numba.njit(cache=True, nogil=True)
def _place(pose, local, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    for r in range(3):
        out[r] = pose[r, 0] * local[0] + pose[r, 1] * local[1] + pose[r, 2] * local[2] + pose[r, 3]


@numba.njit(cache=True, nogil=True)
def pose_links(q, fk, links):  # type: ignore[no-untyped-def]  # pragma: no cover
    """World poses of every link at state q (D,) into links (1, L, 4, 4)."""
    forward_kinematics_kernel(
        q.reshape(1, q.shape[0]), fk[0], fk[1], fk[2], fk[3], fk[4], fk[5], fk[6], fk[7],
        fk[8], fk[9], fk[10], links,
    )  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _place_covers(e, pose, robot, world, placed):  # type: ignore[no-untyped-def]  # pragma: no cover
    if placed[e]:
        return
    count, local = robot[3], robot[4]
    for k in range(count[e]):
        _place(pose, local[e, k], world[e, k])
    placed[e] = True


@numba.njit(cache=True, nogil=True)
def sphere_state(q, fk, robot, scene, pairs, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """FREE, OPEN or COLLIDING (module docstring) for state q (D,).

    robot: (element link (E,), element centre in its link (E, 3), bounding radius (E,),
    cover count (E,), cover centres in the link (E, W, 3), cover radii (E, W), surface reach
    of each centre (E, W)); scene: (kind (M,), rotation (M, 3, 3), position (M, 3), size
    (M, 3), allowed (E, M)); pairs: (i (P,), j (P,)); work: (links (1, L, 4, 4), centres
    (E, 3), cover centres (E, W, 3), placed (E,) bool)."""
    links, centre, world, placed = work[0], work[1], work[2], work[3]
    pose_links(q, fk, links)
    link, local_centre, radius = robot[0], robot[1], robot[2]
    count, cover_r, reach = robot[3], robot[5], robot[6]
    kind, rot, pos, size, allowed = scene[0], scene[1], scene[2], scene[3], scene[4]
    status = FREE
    for e in range(link.shape[0]):
        placed[e] = False
        _place(links[0, link[e]], local_centre[e], centre[e])
    for e in range(link.shape[0]):
        pose = links[0, link[e]]
        for m in range(kind.shape[0]):
            if allowed[e, m]:
                continue
            c = centre[e]
            if signed_distance(kind[m], rot[m], pos[m], size[m], c[0], c[1], c[2]) > radius[e]:
                continue
            _place_covers(e, pose, robot, world, placed)
            for k in range(count[e]):
                w = world[e, k]
                d = signed_distance(kind[m], rot[m], pos[m], size[m], w[0], w[1], w[2])
                if d > cover_r[e, k]:
                    continue
                if kind[m] != MESH and -d > reach[e, k]:
                    return COLLIDING
                status = OPEN
    if status == OPEN:
        return OPEN
    pi, pj = pairs[0], pairs[1]
    for p in range(pi.shape[0]):
        i, j = pi[p], pj[p]
        ci, cj = centre[i], centre[j]
        gap = math.sqrt((ci[0] - cj[0]) ** 2 + (ci[1] - cj[1]) ** 2 + (ci[2] - cj[2]) ** 2)
        if gap > radius[i] + radius[j]:
            continue
        _place_covers(i, links[0, link[i]], robot, world, placed)
        _place_covers(j, links[0, link[j]], robot, world, placed)
        if _covers_meet(i, j, count, world, cover_r, centre, radius):
            return OPEN
    return FREE


@numba.njit(cache=True, nogil=True)
def _covers_meet(i, j, count, world, cover_r, centre, radius):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether some cover ball of element i meets some of element j (balls of one that miss
    the other's bounding ball are skipped)."""
    for a in range(count[i]):
        wa = world[i, a]
        cj = centre[j]
        if np.sqrt(np.sum((wa - cj) ** 2)) > cover_r[i, a] + radius[j]:
            continue
        for b in range(count[j]):
            wb = world[j, b]
            d = math.sqrt((wa[0] - wb[0]) ** 2 + (wa[1] - wb[1]) ** 2 + (wa[2] - wb[2]) ** 2)
            if d <= cover_r[i, a] + cover_r[j, b]:
                return True
    return False
