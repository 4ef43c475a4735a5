"""Error responses declared on the routes, for the OpenAPI document (`responses=` of a route)."""

from __future__ import annotations

from typing import Any

from trajcache.api.schemas.errors import ErrorOut
from trajcache.services.errors import DATABASE_UNAVAILABLE

Responses = dict[int | str, dict[str, Any]]

DB_UNAVAILABLE = (
    "The database is unreachable; the service recovers by itself when it is back",
    DATABASE_UNAVAILABLE,
)
UNAUTHENTICATED = (
    "No API key, or an unknown or revoked one (when key checks are on)",
    "an API key is required: send 'Authorization: Bearer <key>' or 'X-API-Key'",
)
FORBIDDEN = (
    "The key's role may not call this route, or a robot key names another robot",
    "a robot key may not DELETE /trajectories/{trajectory_id} (admin only)",
)
INVALID_REQUEST = (
    "Invalid request: the detail names each invalid field",
    "body.start[1]: Input should be a finite number",
)


def errors(declared: dict[int, tuple[str, str]]) -> Responses:
    """`{status: (description, example detail)}` as OpenAPI responses with the error body."""
    return {
        status: {
            "model": ErrorOut,
            "description": description,
            "content": {"application/json": {"example": {"detail": detail}}},
        }
        for status, (description, detail) in declared.items()
    }


COMMON = errors({401: UNAUTHENTICATED, 403: FORBIDDEN, 422: INVALID_REQUEST, 503: DB_UNAVAILABLE})
"""Errors every /v1 route can answer (declared on the routers; routes add their own)."""
