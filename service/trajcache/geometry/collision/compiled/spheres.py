"""One robot state against the scene and itself on sphere trees, compiled: free, open or
colliding, for planners whose whole loop is compiled (`planning/compiled/`).

The robot is its elements' sphere trees (`model/sphere_tree.py`: every ball holds what its
subtree's leaves cover, and the leaves cover all of the element FCL tests: a mesh's triangles,
a primitive's solid). A scene object is its exact primitive (box, sphere, cylinder, capsule)
or, for a mesh, its oriented bounding box. With sd(p) the signed distance from a point p to
the object (negative inside):

- FREE for an (element, object) row when every branch of the element's tree ends in a ball
  (c, r) with sd(c) > r: that ball, which holds its subtree's part of the element, misses the
  object. A self-collision pair is free when every pair of branches of the two trees ends in
  two balls that are apart. A state is FREE when every row and pair is: the proof is the
  trees'. A pair with a distance table (`pair_tables.py`: one or two joints move it) is free
  first where the table's bound is positive.
- COLLIDING when a leaf's centre lies deeper inside a (non-mesh) object than the leaf's reach
  r(c), the distance from c to the nearest point of the element FCL tests: that point is
  within r(c) of c, so it lies inside the object's solid, which is a collision for FCL too.
  Nothing else is called colliding.
- OPEN otherwise: the trees neither prove the state free nor colliding, and the exact check
  (FCL, in Python) decides. Self-collision pairs are never proven colliding here.

`sphere_state` returns 0 (FREE), 1 (OPEN) or 2 (COLLIDING).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from trajcache.geometry.collision.compiled.slabs import self_slabs
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
def _node(k, e, robot, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """World centre of node k of element e's tree, placed once per state."""
    links, world, stamp, clock = work[0], work[1], work[2], work[3]
    if stamp[k] != clock[0]:
        _place(links[0, robot[0][e]], robot[2][k], world[k])
        stamp[k] = clock[0]
    return world[k]


@numba.njit(cache=True, nogil=True)
def _scene_row(e, m, robot, scene, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """FREE, OPEN or COLLIDING for element e and object m, down e's tree."""
    root, radius, first, count, reach = robot[1], robot[3], robot[4], robot[5], robot[6]
    kind, rot, pos, size = scene[0][m], scene[1][m], scene[2][m], scene[3][m]
    stack = work[4]
    stack[0], top, status = root[e], 1, FREE
    while top > 0:
        top -= 1
        k = stack[top]
        w = _node(k, e, robot, work)
        d = signed_distance(kind, rot, pos, size, w[0], w[1], w[2])
        if d > radius[k]:
            continue
        if first[k] < 0:
            if kind != MESH and -d > reach[k]:
                return COLLIDING
            status = OPEN
        elif top + count[k] > stack.shape[0]:
            status = OPEN  # too deep to follow: the exact check decides
        else:
            for c in range(count[k]):
                stack[top] = first[k] + c
                top += 1
    return status


@numba.njit(cache=True, nogil=True)
def _pair_open(i, j, robot, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether leaves of elements i and j meet (down both trees, the larger ball split)."""
    root, radius, first, count = robot[1], robot[3], robot[4], robot[5]
    stack = work[5]
    stack[0, 0], stack[0, 1], top = root[i], root[j], 1
    while top > 0:
        top -= 1
        a, b = stack[top, 0], stack[top, 1]
        wa, wb = _node(a, i, robot, work), _node(b, j, robot, work)
        gap = math.sqrt((wa[0] - wb[0]) ** 2 + (wa[1] - wb[1]) ** 2 + (wa[2] - wb[2]) ** 2)
        if gap > radius[a] + radius[b]:
            continue
        if first[a] < 0 and first[b] < 0:
            return True
        split_a = first[b] < 0 or (first[a] >= 0 and radius[a] >= radius[b])
        k = a if split_a else b
        if top + count[k] > stack.shape[0]:
            return True
        for c in range(count[k]):
            stack[top, 0] = first[k] + c if split_a else a
            stack[top, 1] = b if split_a else first[k] + c
            top += 1
    return False


@numba.njit(cache=True, nogil=True)
def sphere_state(q, fk, robot, scene, pairs, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """FREE, OPEN or COLLIDING (module docstring) for state q (D,).

    robot: (element link (E,), element root node (E,), node centres in their link's frame
    (N, 3), radii (N,), first child (N,) (−1: a leaf), child count (N,), reach (N,), element
    origins (E, 4, 4), support table, element box centres (E, 3) and half extents (E, 3) in the
    element's frame); scene: (kind (M,), rotation (M, 3, 3), position (M, 3),
    size (M, 3), allowed (E, M), poses (M, 3, 4), support table, box half extents (M, 3));
    pairs: (i (P,), j (P,), then the distance tables of `pair_tables.py`); work: (links
    (1, L, 4, 4), world centres (N, 3), stamps (N,),
    clock (1,), stack (S,), pair stack (S, 2), element poses (E, 3, 4), counts (2,) of the
    states checked and of those found OPEN, element box centres (E, 3)).

    Before trees are descended, the cheaper proofs: oriented boxes apart (an element's box
    holds it; an object's box holds it), and for a pair its distance table, the elements'
    bounding balls and separating slabs (`slabs.py`, as the certification uses them)."""
    pose_links(q, fk, work[0])
    work[3][0] += 1
    work[7][0] += 1
    _pose_elements(robot, work)
    allowed = scene[4]
    status = FREE
    poses, box_centre, box_half = work[6], work[8], robot[10]
    for e in range(robot[1].shape[0]):
        for m in range(scene[0].shape[0]):
            if allowed[e, m]:
                continue
            if obb_apart(
                poses[e], box_centre[e], box_half[e], scene[1][m], scene[2][m], scene[7][m]
            ):
                continue
            row = _scene_row(e, m, robot, scene, work)
            if row == COLLIDING:
                return COLLIDING
            if row == OPEN:
                status = OPEN
    if status == OPEN:
        work[7][1] += 1
        return OPEN
    pi, pj = pairs[0], pairs[1]
    for p in range(pi.shape[0]):
        if pairs[2][p, 0] >= 0 and _table_bound(q, p, pairs) > 0.0:
            continue
        if _pair_slab(pi[p], pj[p], robot, work):
            continue
        if _pair_open(pi[p], pj[p], robot, work):
            work[7][1] += 1
            return OPEN
    return FREE


@numba.njit(cache=True, nogil=True)
def obb_apart(ra, ca, ha, rb, cb, hb):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether two oriented boxes (rotation whose columns are the axes, centre, half extents)
    are apart: a separating axis among the 15 of the separating axis theorem. The rotation
    terms are grown by 1e-9 so that round-off never claims a separation."""
    c = np.empty((3, 3))
    a = np.empty((3, 3))
    t = np.empty(3)
    for i in range(3):
        t[i] = ra[0, i] * (cb[0] - ca[0]) + ra[1, i] * (cb[1] - ca[1]) + ra[2, i] * (cb[2] - ca[2])
        for j in range(3):
            c[i, j] = ra[0, i] * rb[0, j] + ra[1, i] * rb[1, j] + ra[2, i] * rb[2, j]
            a[i, j] = abs(c[i, j]) + 1e-9
    for i in range(3):
        if abs(t[i]) > ha[i] + hb[0] * a[i, 0] + hb[1] * a[i, 1] + hb[2] * a[i, 2]:
            return True
    for j in range(3):
        proj = t[0] * c[0, j] + t[1] * c[1, j] + t[2] * c[2, j]
        if abs(proj) > ha[0] * a[0, j] + ha[1] * a[1, j] + ha[2] * a[2, j] + hb[j]:
            return True
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            reach_a = ha[i1] * a[i2, j] + ha[i2] * a[i1, j]
            reach_b = hb[j1] * a[i, j2] + hb[j2] * a[i, j1]
            if abs(t[i2] * c[i1, j] - t[i1] * c[i2, j]) > reach_a + reach_b:
                return True
    return False


@numba.njit(cache=True, nogil=True)
def _pose_elements(robot, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """World poses (E, 3, 4) of the elements into work[6]."""
    links, poses, link, origin = work[0], work[6], robot[0], robot[7]
    for e in range(link.shape[0]):
        frame = links[0, link[e]]
        for r in range(3):
            for c in range(4):
                acc = frame[r, 0] * origin[e, 0, c] + frame[r, 1] * origin[e, 1, c]
                acc += frame[r, 2] * origin[e, 2, c]
                poses[e, r, c] = acc + (frame[r, 3] if c == 3 else 0.0)
        _place(poses[e], robot[9][e], work[8][e])


@numba.njit(cache=True, nogil=True)
def _pair_slab(i, j, robot, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether the elements' bounding balls, or a separating slab (`slabs.self_slabs`, with
    meshes as boxes, then as hulls), prove elements i and j apart."""
    root, radius, poses = robot[1], robot[3], work[6]
    wi, wj = _node(root[i], i, robot, work), _node(root[j], j, robot, work)
    gap = math.sqrt((wi[0] - wj[0]) ** 2 + (wi[1] - wj[1]) ** 2 + (wi[2] - wj[2]) ** 2)
    if gap > radius[root[i]] + radius[root[j]]:
        return True
    centre, half = work[8], robot[10]
    if obb_apart(poses[i], centre[i], half[i], poses[j], centre[j], half[j]):
        return True
    if self_slabs(poses[i], poses[j], robot[8], i, j, False) > 0.0:
        return True
    sup = robot[8]
    if sup[2][i] >= 0 or sup[2][j] >= 0:
        return self_slabs(poses[i], poses[j], sup, i, j, True) > 0.0
    return False


@numba.njit(cache=True, nogil=True)
def _table_bound(q, p, pairs):  # type: ignore[no-untyped-def]  # pragma: no cover
    """A lower bound on pair p's distance at q from its table (`pair_tables.py`)."""
    dofs, start, step, nodes, offset, bound, table = (
        pairs[2], pairs[3], pairs[4], pairs[5], pairs[6], pairs[7], pairs[8],
    )  # fmt: skip
    index, stride, slack = 0, 1, 0.0
    for k in range(1, -1, -1):  # row-major: the last joint varies fastest
        d = dofs[p, k]
        if d < 0:
            continue
        g = int(round((q[d] - start[p, k]) / step[p, k]))  # noqa: RUF046  (compiled)
        g = min(max(g, 0), nodes[p, k] - 1)
        slack += bound[p, k] * abs(q[d] - (start[p, k] + g * step[p, k]))
        index += g * stride
        stride *= nodes[p, k]
    return table[offset[p] + index] - slack
