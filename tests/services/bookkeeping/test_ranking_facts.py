"""Ranking facts kept briefly in memory: fresh entries served, own bookkeeping applied."""

from __future__ import annotations

from datetime import UTC, datetime

from tests.waiting import FakeClock
from trajcache.cache.ranking import CandidateFacts
from trajcache.services.bookkeeping.ranking_facts import RankingFactsCache


def test_facts_are_served_while_fresh_and_read_again_after_the_ttl() -> None:
    clock = FakeClock()
    cache = RankingFactsCache(ttl_s=1.0, clock=clock)
    assert cache.get_many([1, 2]) == ({}, [1, 2])
    cache.put_many({1: CandidateFacts(env={"door": 30.0})})
    found, missing = cache.get_many([1, 2])
    assert found == {1: CandidateFacts(env={"door": 30.0})} and missing == [2]
    clock.advance(0.9)
    assert cache.get_many([1])[1] == []
    clock.advance(0.2)
    assert cache.get_many([1]) == ({}, [1])


def test_own_bookkeeping_updates_streaks_and_real_validations() -> None:
    cache = RankingFactsCache()
    cache.put_many({1: CandidateFacts(consecutive_failures=2), 2: CandidateFacts()})
    at = datetime(2026, 1, 1, tzinfo=UTC)
    cache.record(served=None, failed=[1, 3], real=False, at=at)  # 3 is not cached: skipped
    assert cache.get_many([1])[0][1].consecutive_failures == 3
    cache.record(served=1, failed=[2], real=True, at=at)
    found, missing = cache.get_many([1, 2, 3])
    assert found[1] == CandidateFacts(consecutive_failures=0, last_real_validated_at=at)
    assert found[2].consecutive_failures == 1 and missing == [3]
    cache.record(served=2, failed=[], real=False, at=at)
    assert cache.get_many([2])[0][2] == CandidateFacts()


def test_the_cache_is_bounded() -> None:
    cache = RankingFactsCache(capacity=2)
    cache.put_many({i: CandidateFacts() for i in range(3)})
    assert cache.get_many([0, 1, 2])[1] == [0]
