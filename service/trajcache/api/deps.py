"""Request dependencies as `Annotated` aliases: the service context, a session, settings, paging."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Path, Query, Request
from pydantic import AfterValidator
from sqlalchemy.orm import Session

from trajcache.api.schemas.common import ROBOT_ID_SCHEMA, checked_robot_id
from trajcache.core.config import MAX_PAGE_SIZE, Settings
from trajcache.services.context import ServiceContext
from trajcache.services.errors import InvalidInputError

DEFAULT_PAGE_SIZE = 100
MAX_OFFSET = 2**63 - 1  # the largest OFFSET the databases take (a 64-bit integer)


async def get_ctx(request: Request) -> ServiceContext:
    """The app's ServiceContext (created by the lifespan); async, so no thread-pool hop."""
    ctx: ServiceContext = request.app.state.ctx
    return ctx


CtxDep = Annotated[ServiceContext, Depends(get_ctx)]


def get_settings(ctx: CtxDep) -> Settings:
    """The settings the app was built with."""
    return ctx.settings


SettingsDep = Annotated[Settings, Depends(get_settings)]


def get_session(ctx: CtxDep) -> Iterator[Session]:
    """A session per request, closed afterwards; services commit, nothing here does."""
    with ctx.sessions() as session:
        yield session


SessionDep = Annotated[Session, Depends(get_session)]


RobotIdPath = Annotated[
    str,
    AfterValidator(checked_robot_id),
    Path(
        description="The robot's id: 1-128 letters, digits, `.`, `_`, `:` or `-`, not only dots.",
        json_schema_extra=ROBOT_ID_SCHEMA,
    ),
]


@dataclass(frozen=True)
class Page:
    """Validated `limit` and `offset` query parameters."""

    limit: int
    offset: int


def checked_page_size(limit: int | None, settings: Settings) -> int:
    """`limit`, or the default page size; one above `max_page_size` is a 422 naming the limit."""
    if limit is None:
        return min(DEFAULT_PAGE_SIZE, settings.max_page_size)
    if limit > settings.max_page_size:
        raise InvalidInputError(
            f"query.limit: {limit} is above max_page_size={settings.max_page_size}"
        )
    return limit


def get_page_size(
    settings: SettingsDep,
    limit: Annotated[
        int | None,
        Query(
            ge=1,
            le=MAX_PAGE_SIZE,
            description=f"Page size: at most the service's max_page_size ({MAX_PAGE_SIZE} unless "
            "set lower).",
        ),
    ] = None,
) -> int:
    """The page size asked for (default 100, or max_page_size when that is smaller)."""
    return checked_page_size(limit, settings)


PageSizeDep = Annotated[int, Depends(get_page_size)]


def get_page(
    limit: PageSizeDep,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET, description="Items to skip.")] = 0,
) -> Page:
    """The page asked for: its size (see get_page_size) and offset."""
    return Page(limit=limit, offset=offset)


PageDep = Annotated[Page, Depends(get_page)]
