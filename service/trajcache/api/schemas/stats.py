"""Response bodies of the statistics, plan-event and trajectory-usage endpoints."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import AliasChoices, BaseModel, ConfigDict, Field, field_validator

from trajcache.api.schemas.rejections import RejectedCandidateOut
from trajcache.api.schemas.trajectories import TrajectoryOut

GroupBy = Literal["robot", "model", "source"]
Requester = Literal["robot", "seed_job"]

_LATENCY = {"sum_ms": 1520.4, "p50": 5.6, "p95": 14.1, "p99": 21.7}
_METRICS: dict[str, Any] = {
    "requests": 272,
    "hits": 253,
    "repaired": 0,
    "planner_calls": 19,
    "misses": 0,
    "failures": 1,
    "refusals": 2,
    "hit_rate": 0.9301,
    "time_saved_ms": 17204.0,
    "uncredited_hits": 0,
    "lookup_ms": {"sum_ms": 101.2, "p50": 0.38, "p95": 0.71, "p99": 0.9},
    "validate_ms": _LATENCY,
    "plan_ms": {"sum_ms": 1292.0, "p50": 68.0, "p95": 140.2, "p99": 180.4},
    "total_ms": {"sum_ms": 3120.9, "p50": 7.9, "p95": 92.5, "p99": 170.3},
}
_EVENT: dict[str, Any] = {
    "event_id": 90211,
    "created_at": "2026-11-21T09:14:03.512Z",
    "robot_id": "robot-7",
    "requester": "robot",
    "model_id": "5158592d…",
    "scene_hash": "c1a9…",
    "status": "success",
    "source": "cache",
    "trajectory_id": 4211,
    "candidates_tried": 1,
    "lookup_ms": 0.41,
    "validate_ms": 6.1,
    "plan_ms": 0.0,
    "total_ms": 9.2,
    "error": None,
    "seed": None,
}
EventStatus = Literal["success", "miss", "failure", "error", "refused"]
EventSource = Literal["cache", "planner", "none"]
GoalKind = Literal["joint", "pose", "unknown"]


class LatencyOut(BaseModel):
    """Time spent in one step: the sum and percentiles in ms (null without any value)."""

    model_config = ConfigDict(from_attributes=True)

    sum_ms: float
    p50: float | None
    p95: float | None
    p99: float | None


class MetricsOut(BaseModel):
    """Statistics of a set of plan requests."""

    model_config = ConfigDict(from_attributes=True)

    requests: int
    hits: int = Field(description="Requests served from the cache.")
    repaired: int = Field(
        description="Requests served with a cached path whose failing stretch the planner "
        "replaced (also counted among the planner calls)."
    )
    planner_calls: int = Field(description="Requests that reached the fallback planner.")
    misses: int = Field(description="Requests answered without a path and without planning.")
    failures: int = Field(description="Requests that ended `failure` or `error`.")
    refusals: int = Field(
        description="Plan requests refused without an answer (a 4xx of a plan route, e.g. a goal "
        "in collision; MoveIt's in-band refusals too): not counted in `requests`."
    )
    hit_rate: float | None = Field(description="hits / requests; null without requests.")
    time_saved_ms: float = Field(
        description="Each hit credited with its model's median planning time in the window."
    )
    uncredited_hits: int = Field(
        description="Hits of models without a successful planner call in the window (credited 0)."
    )
    lookup_ms: LatencyOut
    validate_ms: LatencyOut
    plan_ms: LatencyOut = Field(description="Percentiles over planner calls only.")
    total_ms: LatencyOut


class GroupOut(MetricsOut):
    """The statistics of one robot, model or source (`none`: no trajectory returned)."""

    key: str
    requester: Requester | None = Field(
        default=None,
        description="With group_by=robot, who `key` is: a robot, or a seed job (key "
        "`seed-job-<id>`); a group is the pair, so a robot of that name is a group of its own. "
        "Null for the other groupings.",
    )


class BucketOut(MetricsOut):
    """The statistics of one time bucket, starting at `start`."""

    start: datetime


class ModelBasisOut(BaseModel):
    """The median planning time a model's hits were credited with (null: none, credited 0)."""

    model_config = ConfigDict(from_attributes=True)

    model_id: str
    hits: int
    planner_calls: int = Field(description="Successful planner calls the median is taken over.")
    median_plan_ms: float | None


class StatsOut(BaseModel):
    """Plan statistics of a window: totals, per group, and a time series."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "window": "24h",
                    "since": "2026-11-20T10:00:00Z",
                    "until": "2026-11-21T10:00:00Z",
                    "bucket_s": 3600,
                    "group_by": "robot",
                    "percentile_max_relative_error": 0.0593,
                    "totals": _METRICS,
                    "goal_kinds": {"joint": 380, "pose": 32},
                    "groups": [{"key": "robot-7", "requester": "robot", **_METRICS}],
                    "series": [{"start": "2026-11-21T09:00:00Z", **_METRICS}],
                    "time_saved_basis": [
                        {
                            "model_id": "5158592d…",
                            "hits": 253,
                            "planner_calls": 18,
                            "median_plan_ms": 68.0,
                        }
                    ],
                }
            ]
        }
    )

    window: str
    since: datetime
    until: datetime
    bucket_s: int = Field(description="Length of a time-series bucket (s).")
    group_by: GroupBy
    percentile_max_relative_error: float = Field(
        description="Percentiles come from log-spaced histograms and are within this fraction "
        "of the exact value."
    )
    totals: MetricsOut
    goal_kinds: dict[GoalKind, int] = Field(
        description="The window's requests by goal kind: `joint` (a goal state), `pose` (a "
        "link's pose: `goal_pose`, MoveIt position and orientation constraints); `unknown`: "
        "recorded before the kind was. Refusals are not requests."
    )
    groups: list[GroupOut]
    series: list[BucketOut]
    time_saved_basis: list[ModelBasisOut]


class PlanEventOut(BaseModel):
    """One plan request: who asked, how it ended, and where the time went."""

    model_config = ConfigDict(from_attributes=True, json_schema_extra={"examples": [_EVENT]})

    event_id: int = Field(validation_alias=AliasChoices("event_id", "id"))
    created_at: datetime
    robot_id: str
    requester: Requester = Field(
        description="Who asked: a robot, or a seed job (its `robot_id` is `seed-job-<id>`)."
    )
    model_id: str = Field(description="The robot's model (empty: a refusal of an unknown robot).")
    scene_hash: str | None
    status: str = Field(
        description="success, miss, failure or error; `refused`: not answered (a 4xx of a plan "
        "route, or MoveIt's in-band refusal), `error` saying why (never the request body)."
    )
    source: str | None
    trajectory_id: int | None
    candidates_tried: int
    lookup_ms: float
    validate_ms: float
    plan_ms: float
    total_ms: float
    error: str | None
    seed: int | None = Field(
        default=None,
        description="The planner's random seed when the request planned (null for a cache "
        "answer): planning the same problem with it repeats the same search.",
    )
    goal_kind: GoalKind | None = Field(
        default=None,
        description="`joint` (a goal state) or `pose` (a link's pose); null: recorded before "
        "the kind was, or a refusal.",
    )
    rejections: list[RejectedCandidateOut] = Field(
        default_factory=list,
        description="The cached candidates that failed validation, each with its first failing "
        "sample and the link and object (or the two links) at fault.",
    )

    @field_validator("rejections", mode="before")
    @classmethod
    def _none_is_empty(cls, value: Any) -> Any:
        return [] if value is None else value


class PlanEventPageOut(BaseModel):
    """A page of plan events, newest first; pass `next_cursor` as `cursor` for the next page."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [{"items": [_EVENT], "limit": 100, "next_cursor": "MTc5NTI1MzcyNjg5MTo1"}]
        }
    )

    items: list[PlanEventOut]
    limit: int
    next_cursor: str | None


class TopTrajectoryOut(BaseModel):
    """A trajectory among the most reused ones."""

    model_config = ConfigDict(
        from_attributes=True,
        json_schema_extra={
            "examples": [
                {
                    "trajectory_id": 4211,
                    "model_id": "5158592d…",
                    "source": "sim",
                    "robot_id": None,
                    "n_states": 7,
                    "hits": 953,
                    "failures": 2,
                    "last_used_at": "2026-11-21T09:14:03.512Z",
                    "created_at": "2026-11-02T16:40:11.027Z",
                }
            ]
        },
    )

    trajectory_id: int = Field(validation_alias=AliasChoices("trajectory_id", "id"))
    model_id: str
    source: str
    robot_id: str | None
    n_states: int
    hits: int
    failures: int
    last_used_at: datetime | None
    created_at: datetime


class TrajectoryDetailOut(TrajectoryOut):
    """A stored trajectory with its key states and its most recent plan events."""

    usage_history: list[PlanEventOut] = Field(
        description="The most recent plan events that returned or stored it, newest first."
    )
