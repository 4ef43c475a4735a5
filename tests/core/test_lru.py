"""The one LRU: eviction order, size bound, TTL on a fake clock, counts, thread safety."""

from __future__ import annotations

import threading

import pytest

from tests.waiting import FakeClock
from trajcache.core.lru import LRU


def test_least_recently_used_goes_first() -> None:
    cache: LRU[str, int] = LRU(capacity=2)
    cache.put("a", 1)
    cache.put("b", 2)
    assert cache.get("a") == 1  # "b" is now the least recent
    cache.put("c", 3)
    assert "b" not in cache
    assert cache.get("b") is None
    assert cache.get("a") == 1 and cache.get("c") == 3
    assert len(cache) == 2 and (cache.hits, cache.misses) == (3, 1)


def test_put_again_refreshes_recency_and_replaces() -> None:
    cache: LRU[str, int] = LRU(capacity=2)
    cache.put("a", 1)
    cache.put("b", 2)
    cache.put("a", 10)
    cache.put("c", 3)
    assert cache.get("a") == 10 and "b" not in cache


def test_counts_hits_and_misses_and_clear_resets() -> None:
    cache: LRU[str, int] = LRU(capacity=4)
    cache.put("a", 1)
    cache.get("a")
    cache.get("x")
    found, missing = cache.get_many(["a", "y", "z"])
    assert found == {"a": 1} and missing == ["y", "z"]
    assert (cache.hits, cache.misses) == (2, 3)
    cache.clear()
    assert (len(cache), cache.hits, cache.misses) == (0, 0, 0)


def test_size_bound_evicts_by_total_size_and_skips_oversized() -> None:
    cache: LRU[int, bytes] = LRU(max_size=10, size_fn=len)
    cache.put(1, b"xxxx")
    cache.put(2, b"xxxx")
    cache.put(3, b"xxxx")  # 12 bytes: the first goes
    assert 1 not in cache and cache.size == 8
    cache.put(4, b"x" * 11)  # larger than the whole budget: not kept, nothing evicted
    assert 4 not in cache and len(cache) == 2
    cache.discard(2)
    assert cache.size == 4


def test_size_bound_needs_a_size_function() -> None:
    with pytest.raises(ValueError):
        LRU(max_size=10)
    with pytest.raises(ValueError):
        LRU(capacity=0)


def test_entries_expire_after_ttl_on_the_injected_clock() -> None:
    clock = FakeClock()
    cache: LRU[str, int] = LRU(ttl_s=1.0, clock=clock)
    cache.put("a", 1)
    clock.advance(0.5)
    assert cache.get("a") == 1  # reading does not refresh the age
    cache.update("a", lambda v: v + 1)  # nor does updating
    clock.advance(0.5)
    assert cache.get("a") is None
    assert len(cache) == 0
    cache.update("a", lambda v: v + 1)  # absent: nothing happens
    assert "a" not in cache


def test_get_or_build_builds_once_and_keeps_the_first() -> None:
    cache: LRU[str, list[int]] = LRU(capacity=4)
    calls: list[int] = []

    def build() -> list[int]:
        calls.append(1)
        return [len(calls)]

    first = cache.get_or_build("k", build)
    assert cache.get_or_build("k", build) is first
    assert calls == [1]


def test_concurrent_use_keeps_the_bound_and_the_counts() -> None:
    cache: LRU[int, int] = LRU(capacity=50)
    start = threading.Barrier(8)
    errors: list[BaseException] = []

    def work(seed: int) -> None:
        try:
            start.wait(timeout=10)
            for i in range(2000):
                key = (i * 7 + seed) % 100
                if cache.get(key) is None:
                    cache.put(key, key)
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(s,)) for s in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=30)
    assert not errors
    assert len(cache) <= 50
    assert cache.hits + cache.misses == 8 * 2000
    assert all(cache.get(k) in (None, k) for k in range(100))
