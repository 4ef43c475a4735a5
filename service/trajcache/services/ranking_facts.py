"""Ranking facts of cached trajectories, kept in memory briefly so a hit need not read them.

A trajectory's `env` never changes once stored; its failure streak and last real-robot
validation change with the bookkeeping of every plan that tries it. This process applies its own
bookkeeping to the cache as the plan flow submits it; what other replicas wrote is read again
once an entry is older than `ttl_s`. Ranking only orders candidates that are each validated
before one is served, so a fact a moment old can change which valid trajectory is tried first,
never whether an answer is safe.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Iterable
from dataclasses import replace
from datetime import datetime

from trajcache.cache.ranking import CandidateFacts

__all__ = ["RankingFactsCache"]


class RankingFactsCache:
    """Thread-safe LRU of CandidateFacts by trajectory id, each fresh for `ttl_s` seconds."""

    def __init__(self, *, ttl_s: float = 1.0, capacity: int = 100_000) -> None:
        self.ttl_s = ttl_s
        self.capacity = capacity
        self._items: OrderedDict[int, tuple[CandidateFacts, float]] = OrderedDict()
        self._lock = threading.Lock()

    def get_many(self, ids: Iterable[int]) -> tuple[dict[int, CandidateFacts], list[int]]:
        """The fresh facts among `ids`, and the ids to read from the database."""
        now = time.monotonic()
        found: dict[int, CandidateFacts] = {}
        missing: list[int] = []
        with self._lock:
            for i in ids:
                item = self._items.get(i)
                if item is None or now - item[1] > self.ttl_s:
                    missing.append(i)
                else:
                    found[i] = item[0]
        return found, missing

    def put_many(self, facts: dict[int, CandidateFacts]) -> None:
        """Remember facts just read from the database."""
        now = time.monotonic()
        with self._lock:
            for i, value in facts.items():
                self._items[i] = (value, now)
                self._items.move_to_end(i)
            while len(self._items) > self.capacity:
                self._items.popitem(last=False)

    def record(
        self, *, served: int | None, failed: Iterable[int], real: bool, at: datetime
    ) -> None:
        """Apply one plan's bookkeeping (as the database will have it) to the cached entries."""
        with self._lock:
            for i in failed:
                item = self._items.get(i)
                if item is not None:
                    streak = item[0].consecutive_failures + 1
                    self._items[i] = (replace(item[0], consecutive_failures=streak), item[1])
            item = self._items.get(served) if served is not None else None
            if served is not None and item is not None:
                last_real = at if real else item[0].last_real_validated_at
                facts = replace(item[0], consecutive_failures=0, last_real_validated_at=last_real)
                self._items[served] = (facts, item[1])
