"""RRT-Connect and path simplification whose loops run compiled, on sphere trees.

Every state a motion passes through (at the spec's resolution, coarse samples first) is FREE,
OPEN or COLLIDING by `geometry/collision/compiled/spheres.sphere_state`. A motion with a
COLLIDING sample is blocked; one whose samples are all FREE is taken. A motion with OPEN samples
and no COLLIDING one is neither: it goes into the pending buffer and the loop goes on as if it
were blocked. The loop returns to Python after `iterations` iterations (or when the buffer is
full); Python checks the OPEN samples of each pending motion exactly (FCL) and marks it free or
not; the next call first adds the motions found free to their trees. So the spheres decide only
what they prove, and the exact check decides the rest: spheres never make a motion blocked that
the exact check finds free, they only delay it by one round.

Trees: `nodes` (2, C, D), `parent` (2, C), `count` (2,): tree 0 grows from the start, tree 1
from the goal. Pending: `p_tree`, `p_parent`, `p_state` (P, D), `p_target` (the node of the
other tree it reaches, or −1), `p_ok` (set by Python), `p_count` (1,).

The helpers that allocate nothing compile without reference counting (`BORROWED`, as
`spheres.py` explains); they copy values in loops, since numba's slice assignment needs it.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from trajcache.geometry.collision.compiled.spheres import COLLIDING, FREE, OPEN, sphere_state
from trajcache.geometry.model.kernels import BORROWED

SOLVED, ROUND, FULL = 1, 0, -1
WAIT = -2  # `_connect`: a motion that would join the trees awaits the exact check
MIN_GAIN = 0.01  # a random shortcut must save this share of the path length to be checked


@numba.njit(cache=True, nogil=True, **BORROWED)
def _diff(a, b, planar, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    for d in range(a.shape[0]):
        out[d] = b[d] - a[d]
    if planar:
        out[2] = (out[2] + math.pi) % (2.0 * math.pi) - math.pi


@numba.njit(cache=True, nogil=True, **BORROWED)
def distance(a, b, planar):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Euclidean distance, the base angle (when planar) the short way."""
    total = 0.0
    for d in range(a.shape[0]):
        v = b[d] - a[d]
        if planar and d == 2:
            v = (v + math.pi) % (2.0 * math.pi) - math.pi
        total += v * v
    return math.sqrt(total)


@numba.njit(cache=True, nogil=True, **BORROWED)
def sample_count(a, b, space):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Samples of a → b (a excluded): no value steps more than its resolution."""
    step, planar = space[2], space[3]
    need = 1.0
    for d in range(a.shape[0]):
        v = b[d] - a[d]
        if planar and d == 2:
            v = (v + math.pi) % (2.0 * math.pi) - math.pi
        need = max(need, abs(v) / step[d])
    return int(math.ceil(need - 1e-9))  # noqa: RUF046  (an integer in compiled code too)


@numba.njit(cache=True, nogil=True, **BORROWED)
def _at(a, b, k, n, planar, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The state k/n of the way a → b into out."""
    t = k / n
    for d in range(a.shape[0]):
        v = b[d] - a[d]
        if planar and d == 2:
            v = (v + math.pi) % (2.0 * math.pi) - math.pi
        out[d] = a[d] + t * v
    if planar:
        out[2] = (out[2] + math.pi) % (2.0 * math.pi) - math.pi
    if k == n:
        for d in range(a.shape[0]):
            out[d] = b[d]


@numba.njit(cache=True, nogil=True)
def motion(a, b, space, fk, robot, scene, pairs, work, open_out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """FREE, OPEN or COLLIDING for the motion a → b (a excluded); samples coarse first, the
    end first. With `open_out` of at least n rows, the OPEN samples are written to it and
    their count is the second result."""
    n = sample_count(a, b, space)
    q = np.empty(a.shape[0])
    status, opened = FREE, 0
    top = 1
    while top * 2 <= n:
        top *= 2
    stride, k = top, n  # the end first, then odd multiples of each stride, coarse to fine
    while True:
        _at(a, b, k, n, space[3], q)
        s = sphere_state(q, fk, robot, scene, pairs, work)
        if s == COLLIDING:
            return COLLIDING, 0
        if s == OPEN:
            status = OPEN
            if opened < open_out.shape[0]:
                open_out[opened] = q
            opened += 1
        k = stride if k == n else k + 2 * stride
        while k >= n and stride > 1:
            stride //= 2
            k = stride
        if k >= n:
            break
    return status, opened


@numba.njit(cache=True, nogil=True, **BORROWED)
def _nearest(nodes, count, q, planar):  # type: ignore[no-untyped-def]  # pragma: no cover
    best, best_d = 0, np.inf
    for i in range(count):
        d = distance(nodes[i], q, planar)
        if d < best_d:
            best, best_d = i, d
    return best


@numba.njit(cache=True, nogil=True, **BORROWED)
def _steer(a, b, reach, planar, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The state `reach` along a → b, or b when closer; True when that is b."""
    d = distance(a, b, planar)
    if d <= reach:
        for k in range(a.shape[0]):
            out[k] = b[k]
        return True
    _diff(a, b, planar, out)
    for k in range(a.shape[0]):
        out[k] = a[k] + out[k] * (reach / d)
    if planar:
        out[2] = (out[2] + math.pi) % (2.0 * math.pi) - math.pi
    return False


@numba.njit(cache=True, nogil=True, **BORROWED)
def _add(tree, t, parent_index, q):  # type: ignore[no-untyped-def]  # pragma: no cover
    nodes, parent, count = tree[0], tree[1], tree[2]
    n = count[t]
    if n >= nodes.shape[1]:
        return -1
    for d in range(q.shape[0]):
        nodes[t, n, d] = q[d]
    parent[t, n] = parent_index
    count[t] = n + 1
    return n


@numba.njit(cache=True, nogil=True, **BORROWED)
def _pend(pending, t, parent_index, q, target):  # type: ignore[no-untyped-def]  # pragma: no cover
    p_tree, p_parent, p_state, p_target, p_count = (
        pending[0], pending[1], pending[2], pending[3], pending[5],
    )  # fmt: skip
    n = p_count[0]
    if n < p_tree.shape[0]:
        p_tree[n], p_parent[n], p_target[n] = t, parent_index, target
        for d in range(q.shape[0]):
            p_state[n, d] = q[d]
        p_count[0] = n + 1


@numba.njit(cache=True, nogil=True, **BORROWED)
def _trace(tree, t, i, out, start):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Write tree t's branch from node i to its root into out from row `start`; the count."""
    nodes, parent = tree[0], tree[1]
    n = 0
    while i >= 0:
        for d in range(out.shape[1]):
            out[start + n, d] = nodes[t, i, d]
        i = parent[t, i]
        n += 1
    return n


@numba.njit(cache=True, nogil=True)
def _join(tree, t, i, j, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The path start → goal through node i of tree t and node j of the other tree."""
    i0, i1 = (i, j) if t == 0 else (j, i)
    n0 = _trace(tree, 0, i0, out, 0)
    out[:n0] = out[:n0][::-1].copy()
    n1 = _trace(tree, 1, i1, out, n0)
    return n0 + n1


@numba.njit(cache=True, nogil=True)
def _connect(tree, t, target_index, space, fk, robot, scene, pairs, work, pending, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Grow tree 1 − t toward node `target_index` of tree t; the path length when they meet,
    WAIT when the motion that would join them went to the pending buffer."""
    nodes, count = tree[0], tree[2]
    b = 1 - t
    target = nodes[t, target_index]
    q = np.empty(target.shape[0])
    none = np.empty((0, target.shape[0]))
    while True:
        j = _nearest(nodes[b], count[b], target, space[3])
        reached = _steer(nodes[b, j], target, space[4], space[3], q)
        status, _ = motion(nodes[b, j], q, space, fk, robot, scene, pairs, work, none)
        if status == OPEN:
            _pend(pending, b, j, q, target_index if reached else -1)
            return WAIT if reached else 0
        if status != FREE:
            return 0
        k = _add(tree, b, j, q)
        if k < 0:
            return -1
        if reached:
            return _join(tree, b, k, target_index, out)


@numba.njit(cache=True, nogil=True)
def rrt_connect(tree, pending, space, fk, robot, scene, pairs, work, iterations, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Run up to `iterations` iterations: (SOLVED, path length in `out`), (ROUND, 0) or
    (FULL, 0) when a tree is full. Resolved pending motions are added first. A round ends
    early when a motion that would join the trees awaits the exact check."""
    nodes, count = tree[0], tree[2]
    p_tree, p_parent, p_state, p_target, p_ok, p_count = pending
    for k in range(p_count[0]):
        if p_ok[k] != 1:
            continue
        t = p_tree[k]
        added = _add(tree, t, p_parent[k], p_state[k])
        if added < 0:
            return FULL, 0
        if p_target[k] >= 0:
            p_count[0] = 0
            return SOLVED, _join(tree, t, added, p_target[k], out)
    p_count[0] = 0
    lower, upper, planar, reach = space[0], space[1], space[3], space[4]
    dof = lower.shape[0]
    q_rand, q_new = np.empty(dof), np.empty(dof)
    none = np.empty((0, dof))
    t = 0
    for _ in range(iterations):
        if p_count[0] >= p_tree.shape[0]:
            return ROUND, 0
        for d in range(dof):
            q_rand[d] = lower[d] + np.random.random() * (upper[d] - lower[d])
        i = _nearest(nodes[t], count[t], q_rand, planar)
        _steer(nodes[t, i], q_rand, reach, planar, q_new)
        status, _ = motion(nodes[t, i], q_new, space, fk, robot, scene, pairs, work, none)
        if status == OPEN:
            _pend(pending, t, i, q_new, -1)
        elif status == FREE:
            added = _add(tree, t, i, q_new)
            if added < 0:
                return FULL, 0
            length = _connect(tree, t, added, space, fk, robot, scene, pairs, work, pending, out)
            if length == WAIT:
                return ROUND, 0  # the exact check may join the trees now: no need to grow more
            if length < 0:
                return FULL, 0
            if length > 0:
                return SOLVED, length
        t = 1 - t
    return ROUND, 0


@numba.njit(cache=True, nogil=True)
def seed(value):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Seed the compiled code's random generator (this thread's)."""
    np.random.seed(value)


@numba.njit(cache=True, nogil=True)
def _free(a, b, space, fk, robot, scene, pairs, work, none):  # type: ignore[no-untyped-def]  # pragma: no cover
    status, _ = motion(a, b, space, fk, robot, scene, pairs, work, none)
    return status == FREE


@numba.njit(cache=True, nogil=True)
def simplify(path, n, space, fk, robot, scene, pairs, work, iterations):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Shorten path[:n] in place; only motions the trees prove FREE are taken. The count.

    First greedily from the start: from each kept vertex on, the last vertex, else the one
    half as far, and so on, that a FREE motion reaches; then `iterations` shortcuts between
    two points drawn uniformly along the path's length, tried only where the straight motion
    would save `MIN_GAIN` of it (so the checks go to the shortcuts worth having)."""
    none = np.empty((0, path.shape[1]))
    planar = space[3]
    kept, i = 1, 0  # path[:kept] is the result; reads are at i and beyond, writes at kept ≤ i + 1
    while i < n - 1:
        nxt = i + 1
        span = n - 1 - i
        while span >= 2:
            if _free(path[i], path[i + span], space, fk, robot, scene, pairs, work, none):
                nxt = i + span
                break
            span //= 2
        path[kept] = path[nxt]
        kept += 1
        i = nxt
    n = kept
    a, b = np.empty(path.shape[1]), np.empty(path.shape[1])
    along = np.empty(path.shape[0])
    for _ in range(iterations):
        if n < 3 or n + 1 > path.shape[0]:
            break
        along[0] = 0.0
        for k in range(n - 1):
            along[k + 1] = along[k] + distance(path[k], path[k + 1], planar)
        total = along[n - 1]
        s1, s2 = np.random.random() * total, np.random.random() * total
        s1, s2 = min(s1, s2), max(s1, s2)
        i, j = 0, 0
        while i < n - 2 and along[i + 1] <= s1:
            i += 1
        while j < n - 2 and along[j + 1] <= s2:
            j += 1
        if i == j or along[i + 1] <= along[i] or along[j + 1] <= along[j]:
            continue
        fa = (s1 - along[i]) / (along[i + 1] - along[i])
        fb = (s2 - along[j]) / (along[j + 1] - along[j])
        _at(path[i], path[i + 1], fa, 1.0, planar, a)
        _at(path[j], path[j + 1], fb, 1.0, planar, b)
        if distance(a, b, planar) > (s2 - s1) - MIN_GAIN * total:
            continue
        if _free(a, b, space, fk, robot, scene, pairs, work, none):
            tail = path[j + 1 : n].copy()  # path[i + 1 .. j] become a, b
            path[i + 1] = a
            path[i + 2] = b
            path[i + 3 : i + 3 + tail.shape[0]] = tail
            n = i + 3 + tail.shape[0]
    return n
