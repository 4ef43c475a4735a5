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
- A row or pair the trees leave open is tried as convex shapes (the element's mesh as its
  hull, which holds it; `gjk.py`): a bound above `CLEAR` proves it clear, for FCL too. Rows
  nearer than that wait for the exact check, as all did before: taken at once, they let the
  search hug obstacles, and the paths it found cost more to certify than the search saved
  (MBM Panda, 105 problems in process: at 2 mm certification took 2.75 ms at the median
  against 1.85, at 5 mm 1.91, while the search took 0.96 ms against 1.37 and its mean fell from
  15 to 10 ms).
- OPEN otherwise: neither proves the state free nor colliding, and the exact check (FCL, in
  Python) decides. Self-collision pairs are never proven colliding here.

`sphere_state` returns 0 (FREE), 1 (OPEN) or 2 (COLLIDING). Its arrays:
- robot: element link (E,), element root node (E,), node centres in their link's frame (N, 3),
  radii (N,), first child (N,) (−1: a leaf), child count (N,), reach (N,), element origins
  (E, 4, 4), support table, element box centres (E, 3) and half extents (E, 3) in the element's
  frame;
- scene: kind (M,), rotation (M, 3, 3), position (M, 3), size (M, 3), allowed (E, M), poses
  (M, 3, 4), support table, box half extents (M, 3) and the radius of each box's bounding
  ball (M,), both about the object's position;
- pairs: i (P,), j (P,), then the distance tables of `pair_tables.py`;
- work: links (1, L, 4, 4), world centres (N, 3), stamps (N,), clock (1,), stack (S,), pair
  stack (S, 2), element poses (E, 3, 4), counts (2,) of the states checked and of those found
  OPEN, element box centres (E, 3), element pose stamps (E,), every element's root ball (E, 4):
  its placed centre and radius side by side, which every row and pair reads, and GJK's
  scratch simplex (4, 3).

Every kernel here compiles without numba's reference counting (`model/kernels.BORROWED`): they
allocate nothing and return no array, so every array they touch is borrowed from the caller,
which holds it for the call. With counting, each array taken out of a tuple or viewed cost an
atomic increment and decrement, and that was most of a state's time (2.05 → 0.78 µs per state
on the start–goal line of a bookshelf, 6.8 → 2.1 µs on random states). `tests/geometry/
test_kernel_refcounts.py` holds the rule: no such kernel returns an array.
"""

from __future__ import annotations

import math

import numba

from trajcache.geometry.collision.compiled.gjk import convex_lower
from trajcache.geometry.collision.compiled.primitives import box_distance_at
from trajcache.geometry.collision.compiled.slabs import self_slabs
from trajcache.geometry.model.kernels import BORROWED, forward_kinematics_kernel

FREE, OPEN, COLLIDING = 0, 1, 2
CLEAR = 0.005  # metres: an open row or pair proved this far apart is free (module docstring)
BOX, SPHERE, CYLINDER, CAPSULE, MESH = 0, 1, 2, 3, 4


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def signed_distance(kind, rot, pos, size, m, x, y, z):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Signed distance from world point (x, y, z) to object m of kind `kind` (negative
    inside); a mesh is its oriented bounding box (`size` = half extents), which contains it.
    """
    dx, dy, dz = x - pos[m, 0], y - pos[m, 1], z - pos[m, 2]
    px = rot[m, 0, 0] * dx + rot[m, 1, 0] * dy + rot[m, 2, 0] * dz
    py = rot[m, 0, 1] * dx + rot[m, 1, 1] * dy + rot[m, 2, 1] * dz
    pz = rot[m, 0, 2] * dx + rot[m, 1, 2] * dy + rot[m, 2, 2] * dz
    if kind == BOX or kind == MESH:  # noqa: SIM109  (compiled: plain comparisons)
        qx, qy, qz = abs(px) - size[m, 0], abs(py) - size[m, 1], abs(pz) - size[m, 2]
        out = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2 + max(qz, 0.0) ** 2)
        return out + min(max(qx, max(qy, qz)), 0.0)
    if kind == SPHERE:
        return math.sqrt(px * px + py * py + pz * pz) - size[m, 0]
    if kind == CYLINDER:
        dr = math.sqrt(px * px + py * py) - size[m, 0]
        dh = abs(pz) - size[m, 1]
        return math.sqrt(max(dr, 0.0) ** 2 + max(dh, 0.0) ** 2) + min(max(dr, dh), 0.0)
    # capsule: a segment on z of half length size[1], grown by size[0]
    cz = min(max(pz, -size[m, 1]), size[m, 1])
    return math.sqrt(px * px + py * py + (pz - cz) ** 2) - size[m, 0]


@numba.njit(cache=True, nogil=True, **BORROWED)
def pose_links(q, fk, links):  # type: ignore[no-untyped-def]  # pragma: no cover
    """World poses of every link at state q (D,) into links (1, L, 4, 4)."""
    forward_kinematics_kernel(
        q.reshape(1, q.shape[0]), fk[0], fk[1], fk[2], fk[3], fk[4], fk[5], fk[6], fk[7],
        fk[8], fk[9], fk[10], links,
    )  # fmt: skip


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _node(k, link, links, local, world, stamp, clock):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Place node k (of an element on link `link`) in the world (world[k]), once per state."""
    if stamp[k] != clock:
        for r in range(3):
            world[k, r] = (
                links[0, link, r, 0] * local[k, 0] + links[0, link, r, 1] * local[k, 1]
                + links[0, link, r, 2] * local[k, 2] + links[0, link, r, 3]
            )  # fmt: skip
        stamp[k] = clock


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _gap(a, b, world):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Distance between the placed centres of nodes a and b."""
    dx, dy, dz = world[a, 0] - world[b, 0], world[a, 1] - world[b, 1], world[a, 2] - world[b, 2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@numba.njit(cache=True, nogil=True, **BORROWED)
def _scene_row(e, m, robot, scene, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """FREE, OPEN or COLLIDING for element e and object m, down e's tree."""
    link, local, radius, first, count, reach = (
        robot[0][e], robot[2], robot[3], robot[4], robot[5], robot[6],
    )  # fmt: skip
    kind, rot, pos, size = scene[0][m], scene[1], scene[2], scene[3]
    links, world, stamp, clock, stack = work[0], work[1], work[2], work[3][0], work[4]
    stack[0], top, status = robot[1][e], 1, FREE
    while top > 0:
        top -= 1
        k = stack[top]
        _node(k, link, links, local, world, stamp, clock)
        d = signed_distance(kind, rot, pos, size, m, world[k, 0], world[k, 1], world[k, 2])
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


@numba.njit(cache=True, nogil=True, **BORROWED)
def _pair_open(i, j, robot, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether leaves of elements i and j meet (down both trees, the larger ball split)."""
    link_i, link_j, local, radius, first, count = (
        robot[0][i], robot[0][j], robot[2], robot[3], robot[4], robot[5],
    )  # fmt: skip
    links, world, stamp, clock, stack = work[0], work[1], work[2], work[3][0], work[5]
    stack[0, 0], stack[0, 1], top = robot[1][i], robot[1][j], 1
    while top > 0:
        top -= 1
        a, b = stack[top, 0], stack[top, 1]
        _node(a, link_i, links, local, world, stamp, clock)
        _node(b, link_j, links, local, world, stamp, clock)
        if _gap(a, b, world) > radius[a] + radius[b]:
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


@numba.njit(cache=True, nogil=True, **BORROWED)
def sphere_state(q, fk, robot, scene, pairs, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """FREE, OPEN or COLLIDING (module docstring) for state q (D,); the arrays as the module
    docstring lays them out.

    Before trees are descended, the cheaper proofs: for a scene row, the element's root ball
    (which holds all its tree covers) missing the object's box (first its bounding ball: the box
    lies within it, so this only skips a box test that would pass), then the oriented boxes
    apart (an element's box holds it; an object's box holds it); for a pair its distance table,
    the elements' root balls apart, their boxes apart and separating slabs (`slabs.py`). Every
    root ball is placed once per state, first; an element's pose only when a box test needs it."""
    pose_links(q, fk, work[0])
    work[3][0] += 1
    work[7][0] += 1
    _place_roots(robot, work)
    root = robot[1]
    allowed = scene[4]
    status = FREE
    poses, box_centre, box_half = work[6], work[8], robot[10]
    rot_m, centre_m, half_m, ball_m = scene[1], scene[2], scene[7], scene[8]
    balls = work[10]
    for e in range(root.shape[0]):
        x, y, z, r = balls[e, 0], balls[e, 1], balls[e, 2], balls[e, 3]
        for m in range(scene[0].shape[0]):
            if allowed[e, m]:
                continue
            dx, dy, dz = x - centre_m[m, 0], y - centre_m[m, 1], z - centre_m[m, 2]
            if dx * dx + dy * dy + dz * dz > (r + ball_m[m]) ** 2:
                continue  # the element's bounding ball misses the ball that holds the box
            if box_distance_at(x, y, z, rot_m, centre_m, half_m, m) > r:
                continue  # the element's bounding ball misses the object's box
            _pose_element(e, robot, work)
            if obb_apart(poses, e, box_centre, box_half, rot_m, m, centre_m, half_m):
                continue
            row = _scene_row(e, m, robot, scene, work)
            if row == COLLIDING:
                return COLLIDING
            if row == OPEN and not _convex_apart(e, m, robot, scene, work):
                status = OPEN
    if status == OPEN:
        work[7][1] += 1
        return OPEN
    pi, pj, dofs = pairs[0], pairs[1], pairs[2]
    for p in range(pi.shape[0]):
        if dofs[p, 0] >= 0 and _table_bound(q, p, pairs) > 0.0:
            continue
        i, j = pi[p], pj[p]
        dx, dy, dz = balls[i, 0] - balls[j, 0], balls[i, 1] - balls[j, 1], balls[i, 2] - balls[j, 2]
        if math.sqrt(dx * dx + dy * dy + dz * dz) > balls[i, 3] + balls[j, 3]:
            continue  # the elements' bounding balls are apart
        _pose_element(i, robot, work)
        _pose_element(j, robot, work)
        if obb_apart(poses, i, box_centre, box_half, poses, j, box_centre, box_half):
            continue
        if _pair_slab(i, j, robot, work):
            continue
        if _pair_open(i, j, robot, work) and not _convex_apart(i, -1 - j, robot, scene, work):
            work[7][1] += 1
            return OPEN
    return FREE


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _axis_terms(ra, i, rb, j, row):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Row `row` of C = R_aᵀ R_b, and of |C| grown by 1e-9."""
    c0 = ra[i, 0, row] * rb[j, 0, 0] + ra[i, 1, row] * rb[j, 1, 0] + ra[i, 2, row] * rb[j, 2, 0]
    c1 = ra[i, 0, row] * rb[j, 0, 1] + ra[i, 1, row] * rb[j, 1, 1] + ra[i, 2, row] * rb[j, 2, 1]
    c2 = ra[i, 0, row] * rb[j, 0, 2] + ra[i, 1, row] * rb[j, 1, 2] + ra[i, 2, row] * rb[j, 2, 2]
    return c0, c1, c2, abs(c0) + 1e-9, abs(c1) + 1e-9, abs(c2) + 1e-9


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def obb_apart(ra, i, ca, ha, rb, j, cb, hb):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether oriented boxes i of (ra, ca, ha) and j of (rb, cb, hb) are apart (rotations
    (·, 3, ≥3) whose columns are the axes, centres (·, 3), half extents (·, 3)): a separating
    axis among the 15 of the separating axis theorem. The rotation terms are grown by 1e-9 so
    that round-off never claims a separation. Scalars only: this runs for every (element,
    object) row of every state."""
    dx, dy, dz = cb[j, 0] - ca[i, 0], cb[j, 1] - ca[i, 1], cb[j, 2] - ca[i, 2]
    t0 = ra[i, 0, 0] * dx + ra[i, 1, 0] * dy + ra[i, 2, 0] * dz
    t1 = ra[i, 0, 1] * dx + ra[i, 1, 1] * dy + ra[i, 2, 1] * dz
    t2 = ra[i, 0, 2] * dx + ra[i, 1, 2] * dy + ra[i, 2, 2] * dz
    h0, h1, h2, g0, g1, g2 = ha[i, 0], ha[i, 1], ha[i, 2], hb[j, 0], hb[j, 1], hb[j, 2]
    c00, c01, c02, a00, a01, a02 = _axis_terms(ra, i, rb, j, 0)
    if abs(t0) > h0 + g0 * a00 + g1 * a01 + g2 * a02:
        return True
    c10, c11, c12, a10, a11, a12 = _axis_terms(ra, i, rb, j, 1)
    if abs(t1) > h1 + g0 * a10 + g1 * a11 + g2 * a12:
        return True
    c20, c21, c22, a20, a21, a22 = _axis_terms(ra, i, rb, j, 2)
    if abs(t2) > h2 + g0 * a20 + g1 * a21 + g2 * a22:
        return True
    if abs(t0 * c00 + t1 * c10 + t2 * c20) > h0 * a00 + h1 * a10 + h2 * a20 + g0:
        return True
    if abs(t0 * c01 + t1 * c11 + t2 * c21) > h0 * a01 + h1 * a11 + h2 * a21 + g1:
        return True
    if abs(t0 * c02 + t1 * c12 + t2 * c22) > h0 * a02 + h1 * a12 + h2 * a22 + g2:
        return True
    # the nine cross axes A_i × B_j: |t·(A_i × B_j)| against both boxes' reach along it
    if abs(t2 * c10 - t1 * c20) > h1 * a20 + h2 * a10 + g1 * a02 + g2 * a01:
        return True
    if abs(t2 * c11 - t1 * c21) > h1 * a21 + h2 * a11 + g0 * a02 + g2 * a00:
        return True
    if abs(t2 * c12 - t1 * c22) > h1 * a22 + h2 * a12 + g0 * a01 + g1 * a00:
        return True
    if abs(t0 * c20 - t2 * c00) > h0 * a20 + h2 * a00 + g1 * a12 + g2 * a11:
        return True
    if abs(t0 * c21 - t2 * c01) > h0 * a21 + h2 * a01 + g0 * a12 + g2 * a10:
        return True
    if abs(t0 * c22 - t2 * c02) > h0 * a22 + h2 * a02 + g0 * a11 + g1 * a10:
        return True
    if abs(t1 * c00 - t0 * c10) > h0 * a10 + h1 * a00 + g1 * a22 + g2 * a21:
        return True
    if abs(t1 * c01 - t0 * c11) > h0 * a11 + h1 * a01 + g0 * a22 + g2 * a20:
        return True
    return abs(t1 * c02 - t0 * c12) > h0 * a12 + h1 * a02 + g0 * a21 + g1 * a20


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _place_roots(robot, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Every element's root ball centre placed in the world (work[1], stamped), and copied with
    its radius into work[10] (E, 4), which the loops after read for every row and pair: a few
    cache lines, where the nodes' rows lie far apart (TIAGo, 948 pairs: 5.4 → 4.5 µs a state)."""
    links, link, node, radius = work[0], robot[0], robot[2], robot[3]
    root, world, stamp, clock, balls = robot[1], work[1], work[2], work[3][0], work[10]
    for e in range(link.shape[0]):
        f, k = link[e], root[e]  # written out: a call per element costs more than this
        for r in range(3):
            world[k, r] = (
                links[0, f, r, 0] * node[k, 0] + links[0, f, r, 1] * node[k, 1]
                + links[0, f, r, 2] * node[k, 2] + links[0, f, r, 3]
            )  # fmt: skip
            balls[e, r] = world[k, r]
        balls[e, 3] = radius[k]
        stamp[k] = clock


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _pose_element(e, robot, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Element e's world pose (3, 4) into work[6][e] and its box centre into work[8][e], once
    per state (stamped in work[9]): only rows and pairs that reach a box test need them."""
    links, poses, origin, local, centre = work[0], work[6], robot[7], robot[9], work[8]
    stamp, clock = work[9], work[3][0]
    if stamp[e] == clock:
        return
    f = robot[0][e]
    for r in range(3):
        for c in range(4):
            acc = links[0, f, r, 0] * origin[e, 0, c] + links[0, f, r, 1] * origin[e, 1, c]
            acc += links[0, f, r, 2] * origin[e, 2, c]
            poses[e, r, c] = acc + (links[0, f, r, 3] if c == 3 else 0.0)
    for r in range(3):
        centre[e, r] = (
            poses[e, r, 0] * local[e, 0] + poses[e, r, 1] * local[e, 1]
            + poses[e, r, 2] * local[e, 2] + poses[e, r, 3]
        )  # fmt: skip
    stamp[e] = clock


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
def _convex_apart(e, other, robot, scene, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether GJK's bound proves element e more than `CLEAR` from object `other` (≥ 0), or
    from element −1 − `other` (< 0), meshes as their hulls; the elements posed (work[6])."""
    poses, sup, simplex = work[6], robot[8], work[11]
    if other >= 0:
        return (
            convex_lower(poses[e], sup, e, scene[5][other], scene[6], other, CLEAR, simplex) > CLEAR
        )
    j = -1 - other
    return convex_lower(poses[e], sup, e, poses[j], sup, j, CLEAR, simplex) > CLEAR


@numba.njit(cache=True, nogil=True, **BORROWED)
def _pair_slab(i, j, robot, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether a separating slab (`slabs.self_slabs`, with meshes as boxes, then as hulls)
    proves elements i and j apart."""
    poses, sup = work[6], robot[8]
    if self_slabs(poses[i], poses[j], sup, i, j, False) > 0.0:
        return True
    if sup[2][i] >= 0 or sup[2][j] >= 0:
        return self_slabs(poses[i], poses[j], sup, i, j, True) > 0.0
    return False


@numba.njit(cache=True, nogil=True, inline="always", **BORROWED)
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
