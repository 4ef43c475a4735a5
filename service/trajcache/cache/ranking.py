"""Ranking of relevant cached candidates beyond distance (a pure function; no database).

The lookup (paper, §3) finds candidates whose start and goal are both within the threshold and
sorts them by the sum of the two distances. Ranking keeps that distance as the first criterion
and adjusts it with three rules, each switchable and weighted in distance units:

1. Environment nearness (the paper's "environment-dependent indexing", §5): a candidate
   recorded with environment values near the requesting scene's (door and seat angles) is
   more likely to be valid there. ``+ env_weight · Σ_k min(|e_req[k] − e_cand[k]|, env_cap)``
   over the request's values; a value the candidate did not record counts as ``env_cap``.
2. Real-robot validation: a candidate that recently passed validation on a real robot is
   preferred. ``− real_bonus · (1 − age / real_window_s)`` while ``age < real_window_s``.
3. Repeated failures: a candidate whose last ``failure_demote_after`` (or more) validations
   in a row failed is tried after every other candidate (a separate tier).

Order: (demoted, adjusted distance, distance, id), so equal scores break ties by distance, then
by id, and the result is deterministic.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import TYPE_CHECKING, Any, Protocol

from trajcache.cache.index import Match

if TYPE_CHECKING:
    from trajcache.core.config import Settings

__all__ = [
    "RANKING_COLUMNS",
    "CandidateFacts",
    "RankingRules",
    "env_distance",
    "facts_from_row",
    "rank_matches",
    "ranking_key",
]

# Trajectory columns ranking reads (besides the distance the index already gives).
RANKING_COLUMNS = ("id", "env", "last_real_validated_at", "consecutive_failures")
_DAY_S = 24 * 3600.0


@dataclass(frozen=True)
class RankingRules:
    """Which rules apply and how much each is worth (distance units); see the module docstring."""

    env_enabled: bool = True
    env_weight: float = 0.05
    env_cap: float = 1.0
    real_enabled: bool = True
    real_bonus: float = 0.02
    real_window_s: float = 30 * _DAY_S
    failure_enabled: bool = True
    failure_demote_after: int = 3
    pool: int = 10  # relevant candidates fetched (nearest first) before ranking

    def __post_init__(self) -> None:
        if self.env_weight < 0 or self.real_bonus < 0:
            raise ValueError("ranking weights must not be negative")
        if self.env_cap <= 0 or self.real_window_s <= 0:
            raise ValueError("env_cap and real_window_s must be positive")
        if self.failure_demote_after < 1 or self.pool < 1:
            raise ValueError("failure_demote_after and pool must be at least 1")

    @property
    def active(self) -> bool:
        """Whether any rule can reorder candidates (if not, lookup's order is final)."""
        return self.env_enabled or self.real_enabled or self.failure_enabled

    @classmethod
    def from_settings(cls, settings: Settings) -> RankingRules:
        """The rules configured by the `ranking_*` settings."""
        return cls(
            env_enabled=settings.ranking_env_enabled,
            env_weight=settings.ranking_env_weight,
            env_cap=settings.ranking_env_cap,
            real_enabled=settings.ranking_real_enabled,
            real_bonus=settings.ranking_real_bonus,
            real_window_s=settings.ranking_real_window_s,
            failure_enabled=settings.ranking_failure_enabled,
            failure_demote_after=settings.ranking_failure_demote_after,
            pool=settings.ranking_pool,
        )


@dataclass(frozen=True)
class CandidateFacts:
    """What ranking knows about one cached trajectory besides its distance."""

    env: Mapping[str, float] = field(default_factory=dict)
    last_real_validated_at: datetime | None = None
    consecutive_failures: int = 0


class _TrajectoryLike(Protocol):
    env: Any
    last_real_validated_at: datetime | None
    consecutive_failures: int


def facts_from_row(row: _TrajectoryLike) -> CandidateFacts:
    """The facts of a row (ORM object or result row) with the RANKING_COLUMNS."""
    env = row.env if isinstance(row.env, Mapping) else {}
    return CandidateFacts(
        env={str(k): float(v) for k, v in env.items()},
        last_real_validated_at=row.last_real_validated_at,
        consecutive_failures=int(row.consecutive_failures or 0),
    )


def env_distance(
    requested: Mapping[str, float], recorded: Mapping[str, float], cap: float
) -> float:
    """Σ over the requested values of min(|difference|, cap); unrecorded values count as cap."""
    total = 0.0
    for key, value in requested.items():
        other = recorded.get(key)
        total += cap if other is None else min(abs(float(value) - float(other)), cap)
    return total


def _real_bonus(facts: CandidateFacts, now: datetime, rules: RankingRules) -> float:
    when = facts.last_real_validated_at
    if when is None:
        return 0.0
    age = max(0.0, (now - when).total_seconds())
    if age >= rules.real_window_s:
        return 0.0
    return rules.real_bonus * (1.0 - age / rules.real_window_s)


def ranking_key(
    match: Match,
    facts: CandidateFacts | None,
    *,
    env: Mapping[str, float],
    now: datetime,
    rules: RankingRules,
) -> tuple[int, float, float, int]:
    """Sort key of one candidate: (demoted tier, adjusted distance, distance, id).

    Without facts (a row deleted since the lookup) the key is the distance alone.
    """
    adjusted = match.score
    if facts is None:
        return (0, adjusted, match.score, match.trajectory_id)
    if rules.env_enabled and env:
        adjusted += rules.env_weight * env_distance(env, facts.env, rules.env_cap)
    if rules.real_enabled:
        adjusted -= _real_bonus(facts, now, rules)
    demoted = rules.failure_enabled and facts.consecutive_failures >= rules.failure_demote_after
    return (int(demoted), adjusted, match.score, match.trajectory_id)


def rank_matches(
    matches: Sequence[Match],
    facts: Mapping[int, CandidateFacts],
    *,
    env: Mapping[str, float],
    now: datetime,
    rules: RankingRules,
) -> list[Match]:
    """`matches` re-ordered by the rules; a match without facts is ranked on distance alone."""
    return sorted(
        matches,
        key=lambda m: ranking_key(m, facts.get(m.trajectory_id), env=env, now=now, rules=rules),
    )
