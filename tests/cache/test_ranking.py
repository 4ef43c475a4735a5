"""Candidate ranking: distance first, then environment nearness, real validations, failures."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest

from trajcache.cache.index import Match
from trajcache.cache.ranking import (
    CandidateFacts,
    RankingRules,
    env_distance,
    facts_from_row,
    rank_matches,
)
from trajcache.core.config import Settings
from trajcache.db.models import Trajectory

NOW = datetime(2026, 6, 1, 12, 0, tzinfo=UTC)
OFF = RankingRules(env_enabled=False, real_enabled=False, failure_enabled=False)


def match(trajectory_id: int, score: float) -> Match:
    return Match(trajectory_id, False, score / 2, score / 2, score)


def ids(matches: list[Match]) -> list[int]:
    return [m.trajectory_id for m in matches]


def test_without_rules_the_order_is_distance_then_id() -> None:
    matches = [match(3, 0.2), match(1, 0.1), match(2, 0.1), match(4, 0.05)]
    facts = {i: CandidateFacts(env={"door": 1.5}, consecutive_failures=9) for i in range(1, 5)}
    assert ids(rank_matches(matches, facts, env={"door": 0.0}, now=NOW, rules=OFF)) == [4, 1, 2, 3]


def test_env_nearness_puts_the_matching_environment_first() -> None:
    near_env_far = match(1, 0.10)  # recorded with the door at 0.5 rad
    far_env_near = match(2, 0.08)  # recorded with the door at 1.5 rad
    facts = {1: CandidateFacts(env={"door": 0.5}), 2: CandidateFacts(env={"door": 1.5})}
    request_env = {"door": 0.52}
    on = RankingRules(env_weight=0.05, real_enabled=False, failure_enabled=False)
    ranked = rank_matches([far_env_near, near_env_far], facts, env=request_env, now=NOW, rules=on)
    assert ids(ranked) == [1, 2]  # 0.10 + 0.05·0.02 < 0.08 + 0.05·0.98
    off = RankingRules(env_enabled=False, real_enabled=False, failure_enabled=False)
    ranked = rank_matches([near_env_far, far_env_near], facts, env=request_env, now=NOW, rules=off)
    assert ids(ranked) == [2, 1]
    zero = RankingRules(env_weight=0.0, real_enabled=False, failure_enabled=False)
    ranked = rank_matches([near_env_far, far_env_near], facts, env=request_env, now=NOW, rules=zero)
    assert ids(ranked) == [2, 1]


def test_env_rule_never_outweighs_a_large_distance_gap() -> None:
    # The env term is bounded by weight · cap per value: distance stays the first criterion.
    rules = RankingRules(env_weight=0.05, env_cap=1.0, real_enabled=False, failure_enabled=False)
    facts = {1: CandidateFacts(env={"door": 0.0}), 2: CandidateFacts(env={"door": 3.0})}
    ranked = rank_matches(
        [match(1, 0.15), match(2, 0.01)], facts, env={"door": 0.0}, now=NOW, rules=rules
    )
    assert ids(ranked) == [2, 1]  # 0.01 + 0.05 (capped) < 0.15


def test_env_distance_caps_and_counts_unrecorded_values() -> None:
    assert env_distance({"a": 0.0, "b": 1.0}, {"a": 0.25, "b": 1.0, "extra": 9.0}, 1.0) == 0.25
    assert env_distance({"a": 0.0}, {"a": 5.0}, 0.5) == 0.5
    assert env_distance({"a": 0.0, "b": 0.0}, {}, 0.7) == pytest.approx(1.4)
    assert env_distance({}, {"a": 1.0}, 1.0) == 0.0


def test_an_unrecorded_environment_ranks_behind_a_recorded_near_one() -> None:
    facts = {1: CandidateFacts(env={}), 2: CandidateFacts(env={"door": 0.1})}
    rules = RankingRules(real_enabled=False, failure_enabled=False)
    ranked = rank_matches(
        [match(1, 0.05), match(2, 0.06)], facts, env={"door": 0.1}, now=NOW, rules=rules
    )
    assert ids(ranked) == [2, 1]


def test_recent_real_validation_is_preferred_and_fades() -> None:
    rules = RankingRules(
        env_enabled=False, failure_enabled=False, real_bonus=0.02, real_window_s=3600.0
    )
    plain, validated = match(1, 0.10), match(2, 0.11)

    def order(validated_at: datetime | None, r: RankingRules = rules) -> list[int]:
        facts = {2: CandidateFacts(last_real_validated_at=validated_at)}
        return ids(rank_matches([plain, validated], facts, env={}, now=NOW, rules=r))

    assert order(NOW - timedelta(minutes=1)) == [2, 1]  # bonus ≈ 0.0197 > 0.01 gap
    assert order(NOW - timedelta(minutes=40)) == [1, 2]  # bonus ≈ 0.0067 < 0.01 gap
    assert order(NOW - timedelta(hours=2)) == [1, 2]  # outside the window
    assert order(None) == [1, 2]
    assert order(
        NOW - timedelta(minutes=1), RankingRules(env_enabled=False, real_enabled=False)
    ) == [1, 2]


def test_repeated_failures_demote_a_candidate_behind_all_others() -> None:
    rules = RankingRules(env_enabled=False, real_enabled=False, failure_demote_after=3)
    nearest, middle, farthest = match(1, 0.01), match(2, 0.1), match(3, 0.19)

    def order(failures: int, r: RankingRules = rules) -> list[int]:
        facts = {1: CandidateFacts(consecutive_failures=failures)}
        return ids(rank_matches([farthest, middle, nearest], facts, env={}, now=NOW, rules=r))

    assert order(2) == [1, 2, 3]
    assert order(3) == [2, 3, 1]
    assert order(7) == [2, 3, 1]
    assert order(7, RankingRules(env_enabled=False, real_enabled=False, failure_enabled=False)) == [
        1,
        2,
        3,
    ]


def test_demoted_candidates_keep_their_own_order() -> None:
    rules = RankingRules(env_enabled=False, real_enabled=False, failure_demote_after=2)
    facts = {1: CandidateFacts(consecutive_failures=5), 2: CandidateFacts(consecutive_failures=2)}
    ranked = rank_matches(
        [match(2, 0.05), match(1, 0.04), match(3, 0.3)], facts, env={}, now=NOW, rules=rules
    )
    assert ids(ranked) == [3, 1, 2]


def test_a_match_without_facts_is_ranked_on_distance() -> None:
    rules = RankingRules()
    facts = {2: CandidateFacts(env={"door": 0.0})}
    ranked = rank_matches(
        [match(2, 0.05), match(1, 0.04)], facts, env={"door": 0.0}, now=NOW, rules=rules
    )
    assert ids(ranked) == [1, 2]


def test_rules_come_from_the_settings() -> None:
    settings = Settings(
        ranking_env_enabled=False,
        ranking_env_weight=0.3,
        ranking_env_cap=0.5,
        ranking_real_enabled=False,
        ranking_real_bonus=0.04,
        ranking_real_window_s=60.0,
        ranking_failure_enabled=False,
        ranking_failure_demote_after=5,
        ranking_pool=7,
    )
    assert RankingRules.from_settings(settings) == RankingRules(
        env_enabled=False,
        env_weight=0.3,
        env_cap=0.5,
        real_enabled=False,
        real_bonus=0.04,
        real_window_s=60.0,
        failure_enabled=False,
        failure_demote_after=5,
        pool=7,
    )


@pytest.mark.parametrize(
    "fields",
    [{"env_weight": -1.0}, {"real_bonus": -0.1}, {"env_cap": 0.0}, {"failure_demote_after": 0}],
)
def test_invalid_rules_are_rejected(fields: dict[str, float]) -> None:
    with pytest.raises(ValueError):
        RankingRules(**fields)  # type: ignore[arg-type]


def test_facts_from_an_orm_row() -> None:
    row = Trajectory(env={"door": 1}, last_real_validated_at=NOW, consecutive_failures=None)
    facts = facts_from_row(row)
    assert facts == CandidateFacts(env={"door": 1.0}, last_real_validated_at=NOW)


def test_rules_are_inactive_only_when_every_rule_is_off() -> None:
    assert RankingRules().active
    assert RankingRules(env_enabled=False, real_enabled=False).active
    assert not RankingRules(env_enabled=False, real_enabled=False, failure_enabled=False).active
