"""The clearances of stored paths' end segments this process measured, per validation scope.

A hit replaces a stored path's first and last states; `geometry/validation/end_clearance.py`
proves most of each new end segment from the clearance measured along the stored one, in the
same scope (model variant, scene, validator settings: `cache.memo.MemoScope`). They are
measured after a planned path is stored, off the request path (with its quality), and kept
here, bounded, by the scope and the exact bits of the segment's two states. A segment looked
up the other way round finds its clearance reversed.
"""

from __future__ import annotations

import hashlib

import numpy as np

from trajcache.cache.memo import MemoScope
from trajcache.core.lru import LRU
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.validation.end_clearance import SegmentClearance

__all__ = ["EndClearances"]


class EndClearances:
    """Thread-safe LRU of segment clearances by scope and segment, bounded in bytes."""

    def __init__(self, max_bytes: int = 32 * 1024 * 1024) -> None:
        self._entries: LRU[tuple[MemoScope, bytes], SegmentClearance] = LRU(
            max_size=max_bytes, size_fn=_size
        )

    def put(self, scope: MemoScope, segment: FloatArray, clearance: SegmentClearance) -> None:
        """Keep the clearance measured along `segment` (2, D) in `scope`."""
        self._entries.put((scope, _digest(segment)), clearance)

    def get(self, scope: MemoScope, segment: FloatArray) -> SegmentClearance | None:
        """The clearance of `segment` (2, D) in `scope`, run either way; None if unmeasured."""
        found = self._entries.get((scope, _digest(segment)))
        if found is not None:
            return found
        backwards = self._entries.get((scope, _digest(segment[::-1])))
        return None if backwards is None else backwards.reversed()

    def clear(self) -> None:
        """Forget everything."""
        self._entries.clear()

    def __len__(self) -> int:
        return len(self._entries)


def _size(clearance: SegmentClearance) -> int:
    return clearance.fractions.nbytes + clearance.scene.nbytes + clearance.pairs.nbytes + 256


def _digest(segment: FloatArray) -> bytes:
    array = np.ascontiguousarray(segment, dtype=np.float64)
    return hashlib.sha256(array.tobytes()).digest()
