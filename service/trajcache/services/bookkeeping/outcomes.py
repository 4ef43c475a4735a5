"""What one answered plan request leaves behind: its record, its ranking facts, its count.

Whatever the outcome — a hit, a miss, a planner failure, a planned trajectory — the plan flow
describes it as one :class:`PlanOutcome` (its plan event, its timings, the candidate that served
and those that failed) and hands it to :func:`record_outcome`, the one place that:

- queues the usage counters of the candidates and the plan event to the record writer
  (`records`) as one :class:`PlanRecord`, stamped with the writer's clock, with the quality of a
  newly planned trajectory and the certificates its validations proved;
- applies a hit's bookkeeping to the ranking facts at once (`ranking_facts`), so the next
  request ranks with it before the writer has committed it;
- counts the answer in the Prometheus metrics (`metrics.record_plan`) with the status, source
  and requester of its plan event, read from the event itself, and the same timings.

It does so whoever asked (a robot or a seed job), so `/metrics` and `/v1/stats` count the same
requests. Nothing here writes to the database: the writer does, off the request path.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from typing import Any

from trajcache.services.bookkeeping.metrics import record_plan
from trajcache.services.bookkeeping.ranking_facts import RankingFactsCache
from trajcache.services.bookkeeping.record_batch import (
    EventDetails,
    PlanRecord,
    QualityJob,
    WriterJob,
)
from trajcache.services.bookkeeping.records import PlanRecorder
from trajcache.services.catalog.certificates import CertificateWrite

__all__ = ["PlanOutcome", "Requester", "record_outcome"]


class Requester(str, Enum):
    """Who asked for a plan: a robot, or a seed job planning for the simulated fleet."""

    ROBOT = "robot"
    SEED_JOB = "seed_job"


@dataclass(frozen=True)
class PlanOutcome:
    """How one plan request ended, as its bookkeeping keeps it."""

    event: Mapping[str, Any]  # plan_events column values: status, source, requester, timings…
    timings: Mapping[str, float]  # milliseconds per phase and in all, as the event has them
    served: int | None = None  # the cached trajectory a hit returned
    real: bool = False  # asked by a real robot: a hit validates its trajectory in the real world
    failed: tuple[int, ...] = ()  # the cached candidates that failed validation, in order
    details: EventDetails | None = None  # event columns the writer works out (why they failed)
    quality: QualityJob | None = None  # a newly planned trajectory's quality, written with it
    certificates: tuple[CertificateWrite, ...] = ()  # what the request's validations proved
    jobs: tuple[WriterJob, ...] = ()  # work for later requests, done by the writer first


def record_outcome(outcome: PlanOutcome, *, records: PlanRecorder, facts: RankingFactsCache) -> int:
    """Queue the outcome's record, update the ranking facts of a hit, count it in the metrics;
    the record's sequence number in `records`."""
    at = records.now()
    served = outcome.served
    real = outcome.real and served is not None
    record = records.submit(
        PlanRecord(
            at,
            served,
            outcome.failed,
            outcome.event,
            real=real,
            quality=outcome.quality,
            details=outcome.details,
            certificates=outcome.certificates,
            jobs=outcome.jobs,
        )
    )
    if served is not None:
        facts.record(served=served, failed=outcome.failed, real=real, at=at)
    event = outcome.event
    record_plan(
        status=event["status"],
        source=event["source"],
        requester=event["requester"],
        timings=outcome.timings,
    )
    return record
