"""Typed answers of /v1/stats and /v1/plan-events: windows of plan statistics, plan events."""

from __future__ import annotations

from datetime import datetime
from typing import Literal

from trajcache_client._models import PlanEvent, Requester, _Answer

GroupBy = Literal["robot", "model", "source"]
EventStatus = Literal["success", "miss", "failure", "error", "refused"]
EventSource = Literal["cache", "planner", "none"]


class Latency(_Answer):
    """Time spent in one step: the sum and percentiles in ms (None without any value)."""

    sum_ms: float
    p50: float | None
    p95: float | None
    p99: float | None


class Metrics(_Answer):
    """Statistics of a set of plan requests; `hit_rate` is None without requests."""

    requests: int
    hits: int
    repaired: int
    planner_calls: int
    misses: int
    failures: int
    refusals: int  # refused plan requests (a 4xx), not counted in `requests`
    hit_rate: float | None
    time_saved_ms: float
    uncredited_hits: int
    lookup_ms: Latency
    validate_ms: Latency
    plan_ms: Latency
    total_ms: Latency


class StatsGroup(Metrics):
    """The statistics of one robot, model or source (`none`: no trajectory returned); grouped by
    robot, `requester` says whether `key` is a robot or a seed job (None otherwise)."""

    key: str
    requester: Requester | str | None = None


class StatsBucket(Metrics):
    """The statistics of one time bucket, starting at `start`."""

    start: datetime


class ModelBasis(_Answer):
    """The median planning time a model's hits were credited with (None: credited 0)."""

    model_id: str
    hits: int
    planner_calls: int
    median_plan_ms: float | None


class Stats(_Answer):
    """Plan statistics of a window: totals, per group, and a time series."""

    window: str
    since: datetime
    until: datetime
    bucket_s: int
    group_by: GroupBy | str
    percentile_max_relative_error: float
    totals: Metrics
    goal_kinds: dict[str, int]  # the requests by goal kind (GoalKind)
    groups: list[StatsGroup]
    series: list[StatsBucket]
    time_saved_basis: list[ModelBasis]


class TopTrajectory(_Answer):
    """A trajectory among the most reused ones, without its states."""

    trajectory_id: int
    model_id: str
    source: str
    robot_id: str | None
    n_states: int
    hits: int
    failures: int
    last_used_at: datetime | None
    created_at: datetime


class PlanEventPage(_Answer):
    """A page of plan events, newest first; `next_cursor` (None on the last page) continues."""

    items: list[PlanEvent]
    limit: int
    next_cursor: str | None
