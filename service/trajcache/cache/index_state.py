"""The state a `TrajectoryIndex` publishes: immutable KD-tree blocks and snapshots.

A `Snapshot` is never mutated once published; `with_added` and `with_removed` return new ones
(copy-on-write), so readers need no lock.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from trajcache.geometry.model.shapes import FloatArray

IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

_NODE_BYTES = 72  # sizeof(scipy ckdtreenode): 7 intp/pointer fields + 1 double, + split_dim


class Block:
    """An immutable id-sorted main block with its KD-tree and a lazily built arm-only tree."""

    def __init__(self, ids: IntArray, keys: FloatArray, boxsize: FloatArray | None, leafsize: int):
        self.ids = ids
        self.keys = keys
        self.leafsize = leafsize
        self.tree: cKDTree | None = None
        if len(ids):
            self.tree = _make_tree(keys, leafsize, boxsize)
        keys.flags.writeable = False
        self._boxsize = boxsize
        self._arm_tree: cKDTree | None = None
        self._arm_keys = np.empty((0, 0))
        self._lazy_lock = threading.Lock()  # builds either lazy tree once
        self._ends_tree: cKDTree | None = None
        self._ends_keys = np.empty((0, 0))

    def arm_tree(self, cols: IntArray) -> cKDTree | None:
        """The tree over the arm columns only (built on first use)."""
        if self._arm_tree is None and len(self.ids):
            with self._lazy_lock:
                if self._arm_tree is None:
                    self._arm_keys = np.ascontiguousarray(self.keys[:, cols])
                    self._arm_tree = _make_tree(self._arm_keys, self.leafsize, None)
        return self._arm_tree

    def ends_tree(self) -> cKDTree | None:
        """The tree over every entry's two ends as states: row k < n is entry k's start, row
        n + k its goal (built on first use)."""
        if self._ends_tree is None and len(self.ids):
            with self._lazy_lock:
                if self._ends_tree is None:
                    d = self.keys.shape[1] // 2
                    self._ends_keys = np.concatenate([self.keys[:, :d], self.keys[:, d:]])
                    box = None if self._boxsize is None else self._boxsize[:d]
                    self._ends_tree = _make_tree(self._ends_keys, self.leafsize, box)
        return self._ends_tree

    def memory_bytes(self) -> tuple[int, int, int]:
        """Bytes of (ids, keys and main tree; arm-only keys and tree; ends keys and tree)."""
        main = self.ids.nbytes + self.keys.nbytes + _tree_bytes(self.tree)
        arm = self._arm_keys.nbytes + _tree_bytes(self._arm_tree)
        return main, arm, self._ends_keys.nbytes + _tree_bytes(self._ends_tree)


def _make_tree(keys: FloatArray, leafsize: int, boxsize: FloatArray | None) -> cKDTree:
    """A KD-tree over ``keys`` (not copied); median splits, uncompacted nodes.

    Measured at 10⁶ clustered 20-D keys: same query time as the alternatives, 1/5 of the nodes of
    midpoint splits, and half the build time of compacted nodes.
    """
    return cKDTree(keys, leafsize=leafsize, boxsize=boxsize, compact_nodes=False)


def _tree_bytes(tree: cKDTree | None) -> int:
    """Index array and node storage (estimated from the node count) of a tree, not its data."""
    if tree is None:
        return 0
    return int(tree.indices.nbytes + tree.size * _NODE_BYTES)


@dataclass(frozen=True)
class Snapshot:
    """Everything a query needs; never mutated once published."""

    main: Block
    alive: BoolArray  # over main.ids
    n_alive: int
    delta_ids: IntArray
    delta_keys: FloatArray


def with_removed(snap: Snapshot, ids: IntArray) -> Snapshot:
    """Tombstone ``ids`` in the main block and drop them from the delta."""
    alive, n_alive = snap.alive, snap.n_alive
    main_ids = snap.main.ids
    if len(main_ids) and len(ids):
        pos = np.minimum(np.searchsorted(main_ids, ids), len(main_ids) - 1)
        pos = pos[(main_ids[pos] == ids) & alive[pos]]
        if len(pos):
            alive = alive.copy()
            alive[pos] = False
            n_alive -= len(pos)
    keep = ~np.isin(snap.delta_ids, ids)
    if keep.all():
        return replace(snap, alive=alive, n_alive=n_alive)
    return Snapshot(snap.main, alive, n_alive, snap.delta_ids[keep], snap.delta_keys[keep])


def with_added(snap: Snapshot, ids: IntArray, keys: FloatArray) -> Snapshot:
    """Upsert: replace any existing entries with the same ids, then append to the delta."""
    snap = with_removed(snap, ids)
    if len(snap.delta_ids):
        ids, keys = np.concatenate([snap.delta_ids, ids]), np.concatenate([snap.delta_keys, keys])
    return replace(snap, delta_ids=ids, delta_keys=keys)
