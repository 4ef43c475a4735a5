"""Ranking facts of cached trajectories, kept in memory briefly so a hit need not read them.

A trajectory's `env` never changes once stored; its failure streak and last real-robot
validation change with the bookkeeping of every plan that tries it. This process applies its own
bookkeeping to the cache as the plan flow submits it, and knows the facts of a trajectory it
stores from the store; what other replicas wrote is read again once an entry is older than
`ttl_s` (`TRAJCACHE_RANKING_FACTS_TTL_S`, 30 s). Ranking only orders candidates that are each
validated before one is served, so a fact older than another replica's bookkeeping can change
which valid trajectory is tried first, never whether an answer is safe.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import replace
from datetime import datetime

from trajcache.cache.ranking import CandidateFacts
from trajcache.core.lru import LRU

__all__ = ["RankingFactsCache"]


class RankingFactsCache:
    """Thread-safe LRU of CandidateFacts by trajectory id, each fresh for `ttl_s` seconds."""

    def __init__(
        self,
        *,
        ttl_s: float = 1.0,
        capacity: int = 100_000,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.ttl_s = ttl_s
        self.capacity = capacity
        self._items: LRU[int, CandidateFacts] = LRU(capacity=capacity, ttl_s=ttl_s, clock=clock)

    def get_many(self, ids: Iterable[int]) -> tuple[dict[int, CandidateFacts], list[int]]:
        """The fresh facts among `ids`, and the ids to read from the database."""
        return self._items.get_many(ids)

    def put_many(self, facts: dict[int, CandidateFacts]) -> None:
        """Remember facts just read from the database."""
        self._items.put_many(facts.items())

    def record(
        self, *, served: int | None, failed: Iterable[int], real: bool, at: datetime
    ) -> None:
        """Apply one plan's bookkeeping (as the database will have it) to the cached entries."""
        for i in failed:
            self._items.update(
                i, lambda f: replace(f, consecutive_failures=f.consecutive_failures + 1)
            )
        if served is not None:
            self._items.update(
                served,
                lambda f: replace(
                    f,
                    consecutive_failures=0,
                    last_real_validated_at=at if real else f.last_real_validated_at,
                ),
            )

    def clear(self) -> None:
        """Forget every entry."""
        self._items.clear()

    def __len__(self) -> int:
        return len(self._items)
