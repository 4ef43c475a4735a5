"""/v1/stats and /v1/plan-events: plan statistics, the most reused trajectories, plan events."""

from __future__ import annotations

from dataclasses import asdict
from datetime import UTC, datetime
from typing import Annotated

from fastapi import APIRouter, Query
from pydantic import BaseModel, Field

from trajcache.api.deps import PageSizeDep, SessionDep, SettingsDep, checked_page_size
from trajcache.api.responses import COMMON, errors
from trajcache.api.schemas.common import IsoDateTime
from trajcache.api.schemas.stats import (
    BucketOut,
    EventSource,
    EventStatus,
    GoalKind,
    GroupBy,
    GroupOut,
    MetricsOut,
    ModelBasisOut,
    PlanEventOut,
    PlanEventPageOut,
    Requester,
    StatsOut,
    TopTrajectoryOut,
)
from trajcache.services.stats.event_rows import EventFilter
from trajcache.services.stats.events import (
    PlanEventFilter,
    goal_kind_counts,
    list_plan_events,
    top_trajectories,
)
from trajcache.services.stats.histograms import MAX_RELATIVE_ERROR
from trajcache.services.stats.window import WINDOW_PATTERN, parse_window, plan_stats

router = APIRouter(tags=["stats"], responses=COMMON)

RobotFilter = Annotated[str | None, Query(max_length=128, description="Only this robot.")]
ModelFilter = Annotated[str | None, Query(max_length=64, description="Only this model.")]
RequesterFilter = Annotated[
    Requester | None, Query(description="Only the requests of robots, or of seed jobs.")
]
_ISO = "ISO 8601; UTC when no offset."


class StatsQuery(BaseModel):
    """The query of GET /v1/stats: the window, the grouping and the filters."""

    window: str = Field(
        "24h",
        max_length=16,
        description="Length of the window: 30m, 24h, 7d (1m to 366d).",
        json_schema_extra={"pattern": WINDOW_PATTERN},  # parse_window checks it (and more)
    )
    group_by: GroupBy = Field("robot", description="Break the totals down by this.")
    robot_id: str | None = Field(None, max_length=128, description="Only this robot.")
    model_id: str | None = Field(None, max_length=64, description="Only this model.")
    requester: Requester | None = Field(
        None, description="Only the requests of robots, or of seed jobs."
    )


class PlanEventQuery(BaseModel):
    """The query of GET /v1/plan-events besides its page size: a cursor and the filters."""

    cursor: str | None = Field(None, max_length=64, description="next_cursor of a page.")
    robot_id: str | None = Field(None, max_length=128, description="Only this robot.")
    model_id: str | None = Field(None, max_length=64, description="Only this model.")
    status: EventStatus | None = None
    source: EventSource | None = Field(None, description="`none`: no trajectory was returned.")
    requester: Requester | None = Field(
        None, description="Only the requests of robots, or of seed jobs."
    )
    trajectory_id: int | None = Field(None, ge=1, le=2**63 - 1)
    goal_kind: GoalKind | None = Field(
        None, description="Only requests to a goal state (`joint`) or pose (`pose`)."
    )
    since: IsoDateTime | None = Field(None, description=_ISO)
    until: IsoDateTime | None = Field(None, description=_ISO)


@router.get(
    "/stats",
    response_model=StatsOut,
    summary="Hit rate, planner calls, time per step and time saved over a window",
    description="Totals, one entry per robot, model or source (`group_by`; a robot's entry "
    "says whether it is a robot or a seed job, `requester`), and a time series "
    "for charts. The series spans the data: from the window's first event (at least the last "
    "minute; the whole window when it holds none) to now, and `bucket_s` grows with that span: "
    "5 s up to 5 min, 15 s up to 15 min, 1 min up to 3 h, 5 min up to 12 h, 1 h up "
    "to 7 d, 6 h up to 30 d, 1 d up to 90 d, 7 d beyond. A 24-hour window on a service that "
    "has run for ten minutes is charted in 15-second buckets. Time saved credits each cache hit "
    "with the median planning time of its model's successful planner calls in the window; "
    "hits of a model without any are credited nothing and counted in `uncredited_hits`.",
    responses=errors({422: ("Bad window or group", "query.window: '2w' is not a window like …")}),
)
def stats_route(session: SessionDep, query: Annotated[StatsQuery, Query()]) -> StatsOut:
    """Statistics of the plan requests of the last `window`."""
    window, group_by = query.window, query.group_by
    filters = EventFilter(
        robot_id=query.robot_id, model_id=query.model_id, requester=query.requester
    )
    stats = plan_stats(
        session=session, window_s=parse_window(window), group_by=group_by, filters=filters
    )
    kinds = goal_kind_counts(session=session, since=stats.since, until=stats.until, filters=filters)
    return StatsOut(
        window=window.strip(),
        since=stats.since,
        until=stats.until,
        bucket_s=stats.bucket_s,
        group_by=group_by,
        percentile_max_relative_error=round(MAX_RELATIVE_ERROR, 4),
        totals=MetricsOut.model_validate(stats.totals),
        goal_kinds=kinds,
        groups=[
            GroupOut(key=g.key, requester=g.requester, **asdict(g.metrics)) for g in stats.groups
        ],
        series=[BucketOut(start=start, **asdict(m)) for start, m in stats.series],
        time_saved_basis=[ModelBasisOut.model_validate(b) for b in stats.time_saved_basis],
    )


@router.get(
    "/stats/top-trajectories",
    response_model=list[TopTrajectoryOut],
    summary="The most reused trajectories",
    description="Trajectories by hits (then fewest validation failures), without their states.",
)
def top_trajectories_route(
    session: SessionDep,
    settings: SettingsDep,
    limit: Annotated[
        int, Query(ge=1, le=100, description="How many (at most max_page_size).")
    ] = 10,
    model_id: ModelFilter = None,
) -> list[TopTrajectoryOut]:
    """The `limit` most reused trajectories."""
    limit = checked_page_size(limit, settings)
    rows = top_trajectories(session=session, limit=limit, model_id=model_id)
    return [TopTrajectoryOut.model_validate(row) for row in rows]


@router.get(
    "/plan-events",
    response_model=PlanEventPageOut,
    summary="Plan events, newest first, filtered, a page at a time",
    description="Every plan request leaves an event, a robot's or a seed job's (`requester`). "
    "Filters combine; `since` is inclusive and "
    "`until` exclusive. Pages follow a cursor: pass `next_cursor` as `cursor` to continue; "
    "events written meanwhile never shift a page. `next_cursor` is null on the last page.",
    responses=errors(
        {422: ("Bad filter, page size or cursor", "query.limit: 5000 is above max_page_size=1000")}
    ),
)
def plan_events_route(
    session: SessionDep,
    limit: PageSizeDep,
    query: Annotated[PlanEventQuery, Query()],
) -> PlanEventPageOut:
    """A page of plan events matching the filters."""
    page = list_plan_events(
        session=session,
        limit=limit,
        cursor=query.cursor,
        filters=PlanEventFilter(
            robot_id=query.robot_id,
            model_id=query.model_id,
            requester=query.requester,
            status=query.status,
            source=query.source,
            trajectory_id=query.trajectory_id,
            goal_kind=query.goal_kind,
            since=_utc(query.since),
            until=_utc(query.until),
        ),
    )
    return PlanEventPageOut(
        items=[PlanEventOut.model_validate(e) for e in page.items],
        limit=limit,
        next_cursor=page.next_cursor,
    )


def _utc(value: datetime | None) -> datetime | None:
    if value is None or value.tzinfo is not None:
        return value
    return value.replace(tzinfo=UTC)
