"""An answer's outcome recorded in one step: its record queued, a hit's ranking facts updated,
the answer counted in the metrics with its event's status, source and requester."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import cast

from prometheus_client import REGISTRY

from trajcache.cache.ranking import CandidateFacts
from trajcache.services.bookkeeping.outcomes import PlanOutcome, Requester, record_outcome
from trajcache.services.bookkeeping.ranking_facts import RankingFactsCache
from trajcache.services.bookkeeping.records import PlanRecord, PlanRecorder

AT = datetime(2026, 1, 1, tzinfo=UTC)
TIMINGS = {"lookup": 0.5, "validate": 1.5, "plan": 0.0, "db": 0.2, "total": 2.5}


class _Recorder:
    """Keeps what is submitted, stamped with a fixed clock."""

    def __init__(self) -> None:
        self.records: list[PlanRecord] = []

    def now(self) -> datetime:
        return AT

    def submit(self, record: PlanRecord) -> int:
        self.records.append(record)
        return len(self.records)


def _event(status: str, source: str | None, requester: Requester) -> dict[str, object]:
    return {"status": status, "source": source, "requester": requester.value, "robot_id": "r"}


def _count(status: str, source: str, requester: str) -> float:
    labels = {"status": status, "source": source, "requester": requester}
    return REGISTRY.get_sample_value("trajcache_plan_requests_total", labels) or 0.0


def test_a_hit_is_queued_applied_to_the_facts_and_counted() -> None:
    recorder, facts = _Recorder(), RankingFactsCache()
    facts.put_many({4: CandidateFacts(consecutive_failures=2), 9: CandidateFacts()})
    before = _count("success", "cache", "robot")
    outcome = PlanOutcome(
        _event("success", "cache", Requester.ROBOT), TIMINGS, served=4, real=True, failed=(9,)
    )
    seq = record_outcome(outcome, records=cast(PlanRecorder, recorder), facts=facts)
    [record] = recorder.records
    assert seq == 1 and (record.at, record.served, record.failed, record.real) == (
        AT,
        4,
        (9,),
        True,
    )
    assert record.event == outcome.event
    found, _ = facts.get_many([4, 9])
    assert found[4] == CandidateFacts(consecutive_failures=0, last_real_validated_at=AT)
    assert found[9].consecutive_failures == 1
    assert _count("success", "cache", "robot") == before + 1


def test_an_answer_without_a_hit_leaves_the_facts_and_validates_nothing_real() -> None:
    recorder, facts = _Recorder(), RankingFactsCache()
    facts.put_many({9: CandidateFacts()})
    before = _count("miss", "none", "seed_job")
    outcome = PlanOutcome(_event("miss", None, Requester.SEED_JOB), TIMINGS, real=True, failed=(9,))
    record_outcome(outcome, records=cast(PlanRecorder, recorder), facts=facts)
    [record] = recorder.records
    assert (record.served, record.failed, record.real) == (None, (9,), False)
    assert facts.get_many([9])[0][9].consecutive_failures == 0  # the flow applied it already
    assert _count("miss", "none", "seed_job") == before + 1
