"""Trajectory key states kept in memory by id, so that a lookup reads a candidate's states from
the database once (`IndexStore.states`)."""

from __future__ import annotations

from collections.abc import Iterable

from trajcache.core.lru import LRU
from trajcache.geometry.model.shapes import FloatArray

__all__ = ["StatesCache"]


class StatesCache:
    """Thread-safe LRU of trajectory key states by id, bounded by their total size in bytes."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self._items: LRU[int, FloatArray] = LRU(max_size=max_bytes, size_fn=_nbytes)

    def get_many(self, ids: Iterable[int]) -> tuple[dict[int, FloatArray], list[int]]:
        """The cached states among `ids`, and the ids that are not cached."""
        return self._items.get_many(ids)

    def put(self, trajectory_id: int, states: FloatArray) -> FloatArray:
        """Cache `states` (unless larger than the whole budget) and return them."""
        return self._items.put(trajectory_id, states)

    def discard(self, trajectory_id: int) -> None:
        """Forget one trajectory's states."""
        self._items.discard(trajectory_id)

    def clear(self) -> None:
        """Forget every trajectory's states."""
        self._items.clear()

    def __len__(self) -> int:
        return len(self._items)


def _nbytes(states: FloatArray) -> int:
    return int(states.nbytes)
