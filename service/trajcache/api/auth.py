"""Who may call what: API keys checked against one policy table for every /v1 route.

A key is sent as `Authorization: Bearer <key>` or `X-API-Key: <key>`. Each route names the roles
allowed besides `admin` (which may do everything); routes with a `{robot_id}` in their path are
further limited, for `robot` keys, to the robots the key is bound to. A route missing from the
policy is admin-only, so a new endpoint is never open by accident.

When checks are on (`auth_mode`): `on` always; `off` never; `auto` (the default) when the service
binds beyond loopback (`host`) or once any key has been created. Keys are only ever revoked, never
deleted, so in `auto` mode checks stay on after the last key is revoked: a service that once had
keys never silently opens again; an operator who wants it open says so with `auth_mode=off`.
Health checks stay open.
"""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Request
from starlette.concurrency import run_in_threadpool
from starlette.routing import Route

from trajcache.api.deps import CtxDep
from trajcache.api.refusals import mark_authorized
from trajcache.services.catalog.keys import Principal, Role
from trajcache.services.context import ServiceContext
from trajcache.services.errors import AuthenticationError, PermissionDeniedError

R, S = Role.ROBOT, Role.SEEDER
# Where a caller without a valid key reads about keys (never how to switch checks off: that is
# the operator's, in the same section).
KEYS_DOCS = "keys are described in the README's 'API keys' section (README.md#api-keys)"


@dataclass(frozen=True)
class Rule:
    """Roles allowed besides admin; `own_robot`: robot keys only for their bound robot ids."""

    roles: frozenset[Role]
    own_robot: bool = False


def _rule(*roles: Role, own_robot: bool = False) -> Rule:
    return Rule(frozenset(roles), own_robot)


ADMIN_ONLY = _rule()

# (method, route path under /v1) → rule. Anything not listed is admin-only.
POLICY: dict[tuple[str, str], Rule] = {
    ("GET", "/robot-models"): _rule(R, S),
    ("GET", "/robot-models/{model_id}"): _rule(R, S),
    ("POST", "/robot-models"): _rule(S),
    ("GET", "/robots/{robot_id}"): _rule(R, own_robot=True),
    ("GET", "/robots/{robot_id}/scene"): _rule(R, own_robot=True),
    ("PUT", "/robots/{robot_id}/scene"): _rule(R, own_robot=True),
    ("PATCH", "/robots/{robot_id}/scene"): _rule(R, own_robot=True),
    ("POST", "/robots/{robot_id}/plan"): _rule(R, own_robot=True),
    ("POST", "/robots/{robot_id}/motion-plan"): _rule(R, own_robot=True),
    ("POST", "/robots/{robot_id}/ik"): _rule(R, own_robot=True),
    ("POST", "/robots/{robot_id}/cartesian-path"): _rule(R, own_robot=True),
    ("GET", "/trajectories"): _rule(S),
    ("GET", "/trajectories/{trajectory_id}"): _rule(S),
    ("POST", "/trajectories"): _rule(S),
    ("GET", "/seed-jobs"): _rule(S),
    ("GET", "/seed-jobs/{job_id}"): _rule(S),
    ("POST", "/seed-jobs"): _rule(S),
    ("DELETE", "/seed-jobs/{job_id}"): _rule(S),
}


def is_loopback(host: str) -> bool:
    """Whether binding to `host` keeps the service on this machine."""
    if host in ("localhost", ""):
        return host == "localhost"
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def presented_key(request: Request) -> str | None:
    """The key sent with the request, if any."""
    header = request.headers.get("authorization", "")
    scheme, _, value = header.partition(" ")
    if scheme.lower() == "bearer" and value.strip():
        return value.strip()
    key = request.headers.get("x-api-key", "").strip()
    return key or None


def checks_on(ctx: ServiceContext) -> bool:
    """Whether this request must carry a key (see the module docstring)."""
    mode = ctx.settings.auth_mode
    if mode != "auto":
        return mode == "on"
    return not is_loopback(ctx.settings.host) or ctx.keys.any_key(ctx.sessions)


async def authorize(request: Request, ctx: CtxDep) -> Principal | None:
    """Check the request's key against the policy; None when checks are off.

    Answered on the event loop when the key cache knows the answer (the common case), in a
    worker thread when the database must be asked.
    """
    if ctx.settings.auth_mode == "off":
        mark_authorized(request)
        return None
    if ctx.keys.fresh(presented_key(request)):
        principal = _authorize(request, ctx)
    else:
        principal = await run_in_threadpool(_authorize, request, ctx)
    mark_authorized(request)  # its plan refusals are recorded (`api.refusals`)
    return principal


def _authorize(request: Request, ctx: ServiceContext) -> Principal | None:
    if not checks_on(ctx):
        return None
    secret = presented_key(request)
    if secret is None:
        raise AuthenticationError(
            "an API key is required: send 'Authorization: Bearer <key>' or 'X-API-Key: <key>'; "
            f"{KEYS_DOCS}"
        )
    principal = ctx.keys.authenticate(ctx.sessions, secret)
    if principal is None:
        raise AuthenticationError(f"the API key is unknown or revoked; {KEYS_DOCS}")
    if principal.role is Role.ADMIN:
        return principal
    route = request.scope.get("route")
    # The route's template under /v1 picks the rule; messages name the path as requested.
    path = route.path if isinstance(route, Route) else request.url.path
    method = "GET" if request.method.upper() == "HEAD" else request.method.upper()
    rule = POLICY.get((method, path), ADMIN_ONLY)
    if principal.role not in rule.roles:
        raise PermissionDeniedError(
            f"a {principal.role.value} key may not {request.method} {request.url.path}"
            + ("" if rule.roles else " (admin only)")
        )
    if rule.own_robot and principal.role is Role.ROBOT:
        robot_id = str(request.path_params.get("robot_id", ""))
        if robot_id not in principal.robot_ids:
            raise PermissionDeniedError(
                f"this robot key (prefix {principal.prefix}) is not bound to robot {robot_id!r}"
            )
    return principal


PrincipalDep = Annotated[Principal | None, Depends(authorize)]
