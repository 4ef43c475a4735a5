"""In-memory lookup of cached trajectories by (start, goal) similarity (paper section 3, eq. 1–2).

Design: each trajectory is a key ``[start, goal]`` in 2·D dimensions. The relevance test
(``d_base < t`` and ``d_arm < t`` on both ends) implies ``|Δ| < t`` in every coordinate
(``||Δp|| + |Δθ| < t`` bounds ``|Δx|``, ``|Δy|``, ``|Δθ|``), so a Chebyshev (L∞) ball of radius t
is a superset; it is fetched from a scipy ``cKDTree`` (θ columns periodic via ``boxsize``, so the
wrap needs no extra queries) and then filtered exactly by :mod:`trajcache.cache.metric`'s metric,
compiled (:mod:`trajcache.geometry.model.nearness`).

Recent inserts go to a small unsorted delta that the same compiled test reads whole; when it
outgrows ``max(rebuild_min, 4·√n)`` (or tombstones pile up) everything is merged into a new
id-sorted main block whose tree is built off to the side and swapped in. Reads never lock: the
whole state is an immutable snapshot (:mod:`trajcache.cache.index_state`) replaced atomically
under ``_lock`` (copy-on-write), and mutations that land while a rebuild runs are logged and
replayed onto the rebuilt snapshot. ``arm_only`` queries use a second tree over the arm columns
only, built lazily on the first such query (and kept afterwards by every rebuild).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from trajcache.cache.index_state import Block, IntArray, Snapshot, with_added, with_removed
from trajcache.cache.metric import THETA, TWO_PI, check_dimension, state_distance
from trajcache.geometry.model.nearness import relevant_rows
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray

__all__ = ["EndsOf", "Match", "TrajectoryIndex"]

_log = logging.getLogger(__name__)
_BELOW_TWO_PI = float(np.nextafter(TWO_PI, 0.0))
_EPS = 1e-9  # widens the prefilter so float rounding can never drop a true match
_NONE = np.zeros(0, dtype=np.int64)
_NO_FLOATS = np.zeros(0)
# Relevant rows sorted by Python; beyond, numpy is faster (8 µs against 15 at 4 rows, 29 against
# 21 at 128, measured here).
_FEW = 64


@dataclass(frozen=True)
class Match:
    """One relevant cached trajectory: ``reversed`` means it must be played goal → start."""

    trajectory_id: int
    reversed: bool
    d_start: float
    d_goal: float
    score: float


@dataclass(frozen=True)
class EndsOf:
    """Entries with an end near a state (`TrajectoryIndex.ends_near`): ids, whether the near
    end is the goal (the entry played reversed), its distance, and the other end's state."""

    ids: IntArray
    reversed: npt.NDArray[np.bool_]
    distances: FloatArray
    states: FloatArray


_Op = Callable[[Snapshot], Snapshot]


class TrajectoryIndex:
    """Thread-safe in-memory index of one model's trajectories: id → (start, goal)."""

    def __init__(
        self,
        dim: int,
        *,
        base: BaseType,
        rebuild_min: int = 1024,
        background_rebuild: bool = True,
        leafsize: int = 16,
    ) -> None:
        check_dimension(base, dim)
        self.dim = dim
        self.base = base
        self.rebuild_min = rebuild_min
        self.background_rebuild = background_rebuild
        self._leafsize = leafsize
        planar, arm_offset = base is BaseType.PLANAR, base.arm_offset
        self._theta_cols = np.array([THETA, dim + THETA] if planar else [], dtype=np.intp)
        # arm columns of start and goal, interleaved: the arm-only tree's
        self._arm_cols = np.stack([np.arange(arm_offset, dim), np.arange(arm_offset, dim) + dim], 1)
        self._arm_cols = self._arm_cols.reshape(-1)
        self._boxsize: FloatArray | None = None
        if planar:
            self._boxsize = np.zeros(2 * dim)
            self._boxsize[self._theta_cols] = TWO_PI
        self._lock = threading.Lock()  # guards _snap replacement, _log, _rebuild_scheduled
        self._rebuild_lock = threading.Lock()  # one rebuild at a time
        self._log: list[_Op] | None = None  # mutations made while a rebuild is in flight
        self._rebuild_scheduled = False
        self._arm_used = False
        self._snap = self._empty()

    def add(self, ids: npt.ArrayLike, starts: npt.ArrayLike, goals: npt.ArrayLike) -> None:
        """Insert (or replace) a batch: ``ids`` (n,), ``starts`` and ``goals`` (n, D)."""
        id_arr = np.asarray(ids, dtype=np.int64).reshape(-1)
        keys = self._keys(starts, goals)
        if len(id_arr) != len(keys):
            raise ValueError(f"{len(id_arr)} ids for {len(keys)} start/goal pairs")
        if len(id_arr) > 1 and not (np.diff(np.sort(id_arr)) != 0).all():
            raise ValueError("duplicate trajectory ids in one batch")
        self._mutate(lambda s: with_added(s, id_arr, keys))

    def remove(self, ids: npt.ArrayLike) -> None:
        """Remove trajectories by id (unknown ids are ignored)."""
        id_arr = np.unique(np.asarray(ids, dtype=np.int64).reshape(-1))
        self._mutate(lambda s: with_removed(s, id_arr))

    def clear(self) -> None:
        """Remove everything."""
        self._mutate(lambda s: self._empty())

    def rebuild(self) -> None:
        """Merge the delta and drop tombstones into a fresh main block (queries keep running)."""
        with self._rebuild_lock:
            with self._lock:
                snap = self._snap
                self._log = []
                self._rebuild_scheduled = False
            try:
                main, all_alive = snap.main, snap.n_alive == len(snap.main.ids)
                ids = np.concatenate([main.ids[snap.alive], snap.delta_ids])
                keys = np.concatenate(
                    [main.keys if all_alive else main.keys[snap.alive], snap.delta_keys]
                )
                if len(ids) > 1 and not (ids[1:] > ids[:-1]).all():
                    order = np.argsort(ids)
                    ids, keys = ids[order], keys[order]
                block = Block(ids, keys, self._boxsize, self._leafsize)
                if self._arm_used:  # keep arm-only queries fast after the swap
                    block.arm_tree(self._arm_cols)
            except BaseException:
                with self._lock:
                    self._log = None
                raise
            with self._lock:
                fresh = Snapshot(block, np.ones(len(ids), bool), len(ids), *self._empty_delta())
                for op in self._log:
                    fresh = op(fresh)
                self._log = None
                self._snap = fresh

    def __len__(self) -> int:
        snap = self._snap
        return snap.n_alive + len(snap.delta_ids)

    def __contains__(self, trajectory_id: object) -> bool:
        if not isinstance(trajectory_id, int | np.integer):
            return False
        snap = self._snap
        main_ids = snap.main.ids
        pos = int(np.searchsorted(main_ids, trajectory_id))
        if pos < len(main_ids) and main_ids[pos] == trajectory_id and snap.alive[pos]:
            return True
        return bool((snap.delta_ids == trajectory_id).any())

    def ids(self) -> IntArray:
        """All indexed trajectory ids, sorted."""
        snap = self._snap
        return np.sort(np.concatenate([snap.main.ids[snap.alive], snap.delta_ids]))

    @property
    def delta_size(self) -> int:
        """Entries waiting in the unsorted delta buffer."""
        return len(self._snap.delta_ids)

    def memory_bytes(self) -> dict[str, int]:
        """Approximate bytes held by the main block, the arm-only and ends trees (built on
        first use) and the delta buffer."""
        snap = self._snap
        main, arm, ends = snap.main.memory_bytes()
        delta = snap.delta_ids.nbytes + snap.delta_keys.nbytes
        return {"main": main + snap.alive.nbytes, "arm_only": arm, "ends": ends, "delta": delta}

    def delta_limit(self, n_main: int) -> int:
        """Delta size beyond which a rebuild is due, for a main block of ``n_main`` entries."""
        return max(self.rebuild_min, int(4 * np.sqrt(max(n_main, 0))))

    def query(
        self,
        start: npt.ArrayLike,
        goal: npt.ArrayLike,
        *,
        threshold: float = 0.2,
        limit: int = 3,
        arm_only: bool = False,
        goal_threshold: float | None = None,
    ) -> list[Match]:
        """Up to ``limit`` relevant trajectories, best (lowest score, then id) first; with
        ``goal_threshold`` above ``threshold``, the goal end may lie that far (the start end
        within ``threshold``, its base and arm distances summed for a planar base)."""
        if not threshold > 0:
            raise ValueError(f"threshold must be positive, not {threshold}")
        start_within = None
        if goal_threshold is not None and goal_threshold > threshold:
            start_within, threshold = threshold, goal_threshold
        q = self._keys(start, goal)[0]
        arm_only = arm_only and self.base is BaseType.PLANAR
        if arm_only and self.dim == self.base.arm_offset:
            raise ValueError("arm_only queries need arm joints")
        if limit <= 0:
            return []
        snap = self._snap
        d = self.dim
        queries = np.stack([q, np.concatenate([q[d:], q[:d]])])  # forward, reversed
        planar = self.base is BaseType.PLANAR
        parts: list[tuple[IntArray, tuple[IntArray, IntArray, FloatArray, FloatArray]]] = []
        main = snap.main
        self._arm_used |= arm_only
        tree = main.arm_tree(self._arm_cols) if arm_only else main.tree
        if tree is not None:
            tree_queries = queries[:, self._arm_cols] if arm_only else queries
            hits = tree.query_ball_point(
                tree_queries, threshold + _EPS, p=np.inf, return_sorted=False
            )
            rows = np.fromiter(set(hits[0]).union(hits[1]), dtype=np.int64)
            rows = rows[snap.alive[rows]]  # both orientations are tested on either's rows
            found = relevant_rows(main.keys, rows, queries, threshold, planar, arm_only)
            parts.append((main.ids[rows], found))
        if len(snap.delta_ids):
            rows = np.arange(len(snap.delta_ids), dtype=np.int64)
            found = relevant_rows(snap.delta_keys, rows, queries, threshold, planar, arm_only)
            parts.append((snap.delta_ids, found))
        return _best(parts, limit, start_within)

    def ends_near(self, state: npt.ArrayLike, *, threshold: float) -> EndsOf:
        """Every entry one of whose ends lies within ``threshold`` of ``state`` (base and arm
        distances each, as ``query`` measures an end), with its other end's state (θ in
        [−π, π)), nearest first, then by id; an entry both of whose ends do counts twice."""
        if not threshold > 0:
            raise ValueError(f"threshold must be positive, not {threshold}")
        d = self.dim
        at = self._keys(state, state)[0][:d]
        snap = self._snap
        parts: list[tuple[IntArray, IntArray, FloatArray]] = []  # ids, which end, the entry's keys
        tree = snap.main.ends_tree()
        if tree is not None:
            hits = np.asarray(tree.query_ball_point(at, threshold + _EPS, p=np.inf), np.int64)
            n = len(snap.main.ids)
            rows, end = hits % n, hits // n
            live = snap.alive[rows]
            parts.append((snap.main.ids[rows[live]], end[live], snap.main.keys[rows[live]]))
        if len(snap.delta_ids):
            both = np.repeat(np.arange(2, dtype=np.int64), len(snap.delta_ids))
            keys = np.concatenate([snap.delta_keys, snap.delta_keys])
            parts.append((np.concatenate([snap.delta_ids, snap.delta_ids]), both, keys))
        ids = np.concatenate([p[0] for p in parts] or [_NONE])
        end = np.concatenate([p[1] for p in parts] or [_NONE])
        keys = np.concatenate([p[2] for p in parts] or [np.empty((0, 2 * d))])
        goal_end = end[:, None] == 1
        near = np.where(goal_end, keys[:, d:], keys[:, :d])
        far = np.where(goal_end, keys[:, :d], keys[:, d:])
        if self.base is BaseType.PLANAR:
            far[:, THETA] -= np.pi  # keys hold θ + π (`_keys`)
        base_gap, arm_gap = state_distance(near, at, base=self.base)
        keep = (base_gap < threshold) & (arm_gap < threshold)
        gap = (base_gap + arm_gap)[keep]
        order = np.lexsort((end[keep], ids[keep], gap))
        return EndsOf(ids[keep][order], end[keep][order] == 1, gap[order], far[keep][order])

    def _keys(self, starts: npt.ArrayLike, goals: npt.ArrayLike) -> FloatArray:
        """Validate (n, D) starts/goals and pack them as keys with θ mapped into [0, 2π)."""
        s = np.atleast_2d(np.asarray(starts, dtype=np.float64))
        g = np.atleast_2d(np.asarray(goals, dtype=np.float64))
        if s.ndim != 2 or s.shape != g.shape or s.shape[1] != self.dim:
            raise ValueError(f"starts/goals must be (n, {self.dim}); got {s.shape} and {g.shape}")
        keys = np.concatenate([s, g], axis=1)
        if not np.isfinite(keys).all():
            raise ValueError("states must be finite")
        if len(self._theta_cols):
            th = np.mod(keys[:, self._theta_cols] + np.pi, TWO_PI)
            keys[:, self._theta_cols] = np.minimum(th, _BELOW_TWO_PI)
        return keys

    def _empty_delta(self) -> tuple[IntArray, FloatArray]:
        return np.empty(0, np.int64), np.empty((0, 2 * self.dim))

    def _empty(self) -> Snapshot:
        block = Block(np.empty(0, np.int64), np.empty((0, 2 * self.dim)), None, self._leafsize)
        return Snapshot(block, np.empty(0, bool), 0, *self._empty_delta())

    def _mutate(self, op: _Op) -> None:
        """Apply ``op`` to the published snapshot (and to the log if a rebuild is running)."""
        with self._lock:
            snap = op(self._snap)
            self._snap = snap
            if self._log is not None:
                self._log.append(op)
            n_main = len(snap.main.ids)
            due = len(snap.delta_ids) > self.delta_limit(n_main) or (
                n_main - snap.n_alive > max(self.rebuild_min, n_main // 4)
            )
            start = due and not self._rebuild_scheduled
            if start:
                self._rebuild_scheduled = True
        if not start:
            return
        if self.background_rebuild:
            threading.Thread(target=self._rebuild_logged, name="index-rebuild", daemon=True).start()
        else:
            self.rebuild()

    def _rebuild_logged(self) -> None:
        try:
            self.rebuild()
        except Exception:  # a failed rebuild leaves the index correct, just slower
            _log.exception("trajectory index rebuild failed")


def _best(
    parts: list[tuple[IntArray, tuple[IntArray, IntArray, FloatArray, FloatArray]]],
    limit: int,
    start_within: float | None = None,
) -> list[Match]:
    """The relevant rows of `parts` (each: the ids of its tested rows, and `relevant_rows`' answer
    on them), those whose start lies within `start_within` if given, the best orientation per
    id, the first `limit` by score, then id, then forward: sorted in Python when they are few,
    by numpy when many."""
    ids = np.concatenate([part_ids[found[0]] for part_ids, found in parts] or [_NONE])
    rev = np.concatenate([found[1] for _, found in parts] or [_NONE])
    d_start = np.concatenate([found[2] for _, found in parts] or [_NO_FLOATS])
    d_goal = np.concatenate([found[3] for _, found in parts] or [_NO_FLOATS])
    if start_within is not None:
        near = d_start < start_within
        ids, rev, d_start, d_goal = ids[near], rev[near], d_start[near], d_goal[near]
    score = d_start + d_goal
    if len(ids) > _FEW:
        order = np.lexsort((rev, ids, score))
        _, first = np.unique(ids[order], return_index=True)
        keep = order[np.sort(first)[:limit]]
        ids, rev, d_start, d_goal, score = (a[keep] for a in (ids, rev, d_start, d_goal, score))
    columns = (score, ids, rev, d_start, d_goal)
    rows = sorted(zip(*(column.tolist() for column in columns), strict=True))
    best: dict[int, Match] = {}
    for c, i, r, s, g in rows:
        if i not in best:
            best[i] = Match(i, bool(r), s, g, c)
            if len(best) == limit:
                break
    return list(best.values())
