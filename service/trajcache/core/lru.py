"""The one in-memory cache of the service: a thread-safe LRU map with an optional TTL and bound.

- `capacity` bounds the number of entries; `max_size` bounds the sum of `size_fn(value)` (e.g.
  bytes of arrays), and a value larger than `max_size` on its own is not kept at all. Beyond
  either bound the least recently used entries go first.
- `ttl_s` makes an entry stale that long after it was put (not after it was last read): a stale
  entry is a miss and is dropped. `update` changes a value in place without refreshing its age.
- `clock` (monotonic seconds) is injectable so tests expire entries without sleeping.
- Values are built outside the lock (`get_or_build`): two threads missing the same key may both
  build it; the first one put is the one kept and returned to both.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterable
from typing import Generic, TypeVar

__all__ = ["LRU"]

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")

_MISSING = object()


class LRU(Generic[K, V]):
    """Thread-safe least-recently-used map, bounded by count and/or size, with optional TTL."""

    def __init__(
        self,
        *,
        capacity: int | None = None,
        ttl_s: float | None = None,
        max_size: int | None = None,
        size_fn: Callable[[V], int] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if capacity is not None and capacity < 1:
            raise ValueError(f"capacity must be at least 1, not {capacity}")
        if (max_size is None) != (size_fn is None):
            raise ValueError("max_size and size_fn go together")
        self.capacity = capacity
        self.ttl_s = ttl_s
        self.max_size = max_size
        self._size_fn = size_fn
        self._clock = clock
        self._items: OrderedDict[K, tuple[V, float]] = OrderedDict()
        self._size = 0
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    def get(self, key: K) -> V | None:
        """The fresh value of `key` (now the most recent), or None."""
        with self._lock:
            value = self._lookup(key, self._clock())
            if value is _MISSING:
                self.misses += 1
                return None
            self.hits += 1
            return value  # type: ignore[return-value]

    def get_many(self, keys: Iterable[K]) -> tuple[dict[K, V], list[K]]:
        """The fresh values among `keys`, and the keys that missed (in order)."""
        found: dict[K, V] = {}
        missing: list[K] = []
        with self._lock:
            now = self._clock()
            for key in keys:
                value = self._lookup(key, now)
                if value is _MISSING:
                    missing.append(key)
                else:
                    found[key] = value  # type: ignore[assignment]
            self.hits += len(found)
            self.misses += len(missing)
        return found, missing

    def put(self, key: K, value: V) -> V:
        """Store `value` as the most recent entry, evict beyond the bounds, and return it."""
        with self._lock:
            self._store(key, value, self._clock())
        return value

    def put_many(self, items: Iterable[tuple[K, V]]) -> None:
        """Store several values with one lock and one timestamp."""
        with self._lock:
            now = self._clock()
            for key, value in items:
                self._store(key, value, now)

    def get_or_build(self, key: K, build_fn: Callable[[], V]) -> V:
        """The cached value of `key`, else `build_fn()` (run unlocked) cached and returned."""
        found = self.get(key)
        if found is not None:
            return found
        built = build_fn()
        with self._lock:
            now = self._clock()
            value = self._lookup(key, now)
            if value is not _MISSING:  # another thread built it first: share that one
                return value  # type: ignore[return-value]
            self._store(key, built, now)
        return built

    def update(self, key: K, fn: Callable[[V], V]) -> None:
        """Replace the value of `key`, if cached, by `fn(value)`, keeping its age and place."""
        with self._lock:
            item = self._items.get(key)
            if item is not None:
                value = fn(item[0])
                self._resize(item[0], value)
                self._items[key] = (value, item[1])

    def discard(self, key: K) -> None:
        """Forget `key` if cached."""
        with self._lock:
            item = self._items.pop(key, None)
            if item is not None:
                self._resize(item[0], None)

    def clear(self) -> None:
        """Forget every entry and reset the hit and miss counts."""
        with self._lock:
            self._items.clear()
            self._size = 0
            self.hits = self.misses = 0

    @property
    def size(self) -> int:
        """The sum of `size_fn` over the entries (0 without a size function)."""
        return self._size

    def __contains__(self, key: object) -> bool:
        with self._lock:
            item = self._items.get(key)  # type: ignore[arg-type]
            return item is not None and not self._stale(item[1], self._clock())

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)

    def _lookup(self, key: K, now: float) -> object:
        item = self._items.get(key)
        if item is None:
            return _MISSING
        if self._stale(item[1], now):
            del self._items[key]
            self._resize(item[0], None)
            return _MISSING
        self._items.move_to_end(key)
        return item[0]

    def _stale(self, stamp: float, now: float) -> bool:
        return self.ttl_s is not None and now - stamp >= self.ttl_s

    def _store(self, key: K, value: V, now: float) -> None:
        size_fn, limit = self._size_fn, self.max_size
        if size_fn is not None and limit is not None and size_fn(value) > limit:
            return  # larger than the whole budget: evicting everything would not make room
        old = self._items.pop(key, None)
        if old is not None:
            self._resize(old[0], None)
        self._items[key] = (value, now)
        self._resize(None, value)
        while self._items and (
            (self.capacity is not None and len(self._items) > self.capacity)
            or (self.max_size is not None and self._size > self.max_size)
        ):
            _, (evicted, _) = self._items.popitem(last=False)
            self._resize(evicted, None)

    def _resize(self, old: V | None, new: V | None) -> None:
        if self._size_fn is None:
            return
        if old is not None:
            self._size -= self._size_fn(old)
        if new is not None:
            self._size += self._size_fn(new)
