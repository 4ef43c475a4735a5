"""API keys: created once (the secret is shown once), stored as a SHA-256 hash, revocable.

A key looks like `tc_<prefix>_<secret>`; the prefix (8 hex characters) finds the row and is safe
to show in listings and logs. Keys are 256-bit random values, so a plain SHA-256 of the whole key
is a sufficient hash (no salt or slow hash is needed for secrets nobody chose).

Keys are never deleted, only revoked: `any_key_created` stays true once the first key is made, so
revoking every key does not turn checks off (see `api.auth`). Revoking a revoked key is a conflict.

`KeyCache` remembers verified keys for a few seconds so a request costs no database round trip;
a revoked key therefore stops working on every replica within `auth_cache_ttl_s`.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import Enum

import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from trajcache.core.lru import LRU
from trajcache.db.models import ApiKey, utcnow
from trajcache.services.catalog.robots import check_robot_id
from trajcache.services.errors import ConflictError, InvalidInputError, NotFoundError

KEY_PREFIX = "tc"
MAX_ROBOTS_PER_KEY = 1000
_ANY = "any"  # the one entry of KeyCache._any


class Role(str, Enum):
    """What a key may do (SPEC: robot, seeder, admin)."""

    ROBOT = "robot"  # plan, read and write only its own robots' scenes
    SEEDER = "seeder"  # register models, seed jobs, bulk import, read the cache
    ADMIN = "admin"  # everything


@dataclass(frozen=True)
class Principal:
    """Who a verified key belongs to."""

    key_id: int
    name: str
    prefix: str
    role: Role
    robot_ids: frozenset[str]


@dataclass(frozen=True)
class KeyInfo:
    """A key as listed (never the secret)."""

    id: int
    name: str
    prefix: str
    role: str
    robot_ids: list[str]
    created_at: datetime
    revoked_at: datetime | None


def hash_key(secret: str) -> str:
    """The stored form of a key."""
    return hashlib.sha256(secret.encode()).hexdigest()


def create_key(
    *, session: Session, name: str, role: str, robot_ids: list[str] | None = None
) -> tuple[KeyInfo, str]:
    """Create a key; returns its listing and the secret, which is not stored anywhere."""
    name = name.strip()
    if not 1 <= len(name) <= 200:
        raise InvalidInputError("key name must be 1-200 characters")
    try:
        chosen = Role(role)
    except ValueError:
        valid = ", ".join(r.value for r in Role)
        raise InvalidInputError(f"role {role!r} must be one of {valid}") from None
    robots = sorted(set(robot_ids or []))
    for robot_id in robots:
        check_robot_id(robot_id)
    if len(robots) > MAX_ROBOTS_PER_KEY:
        raise InvalidInputError(f"a key may name at most {MAX_ROBOTS_PER_KEY} robots")
    if chosen is Role.ROBOT and not robots:
        raise InvalidInputError("a robot key must name the robot ids it may use")
    if chosen is not Role.ROBOT and robots:
        raise InvalidInputError(f"only robot keys are bound to robot ids, not {chosen.value} keys")
    prefix = secrets.token_hex(4)
    secret = f"{KEY_PREFIX}_{prefix}_{secrets.token_urlsafe(32)}"
    row = ApiKey(
        name=name, prefix=prefix, key_hash=hash_key(secret), role=chosen.value, robot_ids=robots
    )
    session.add(row)
    session.commit()
    return _info(row), secret


def list_keys(*, session: Session, include_revoked: bool = False) -> list[KeyInfo]:
    """All keys, oldest first."""
    query = sa.select(ApiKey).order_by(ApiKey.id)
    if not include_revoked:
        query = query.where(ApiKey.revoked_at.is_(None))
    return [_info(row) for row in session.execute(query).scalars()]


def revoke_key(*, session: Session, key: str) -> KeyInfo:
    """Revoke a key given by prefix (or id); ConflictError if it is revoked already."""
    rows = list(session.execute(sa.select(ApiKey).where(ApiKey.prefix == key)).scalars())
    if not rows and key.isdigit():
        rows = list(session.execute(sa.select(ApiKey).where(ApiKey.id == int(key))).scalars())
    if not rows:
        raise NotFoundError(f"API key {key!r} not found")
    if len(rows) > 1:
        raise InvalidInputError(f"{key!r} names {len(rows)} keys; give the id")
    row = rows[0]
    if row.revoked_at is not None:
        raise ConflictError(
            f"API key #{row.id} ({row.prefix}, {row.name!r}) was already revoked at "
            f"{format_time(row.revoked_at)}"
        )
    row.revoked_at = utcnow()
    session.commit()
    return _info(row)


def any_key_created(session: Session) -> bool:
    """Whether a key was ever created, revoked or not (keys are never deleted)."""
    return session.scalar(sa.select(ApiKey.id).limit(1)) is not None


def format_time(moment: datetime) -> str:
    """`moment` as ISO 8601 to the second with its offset (UTC when stored without one)."""
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=UTC)
    return moment.isoformat(timespec="seconds")


def _info(row: ApiKey) -> KeyInfo:
    return KeyInfo(
        id=row.id,
        name=row.name,
        prefix=row.prefix,
        role=row.role,
        robot_ids=list(row.robot_ids or []),
        created_at=row.created_at,
        revoked_at=row.revoked_at,
    )


def _split(secret: str) -> str | None:
    """The prefix of a well-formed key, else None."""
    parts = secret.split("_", 2)
    if len(parts) != 3 or parts[0] != KEY_PREFIX or len(parts[1]) != 8 or len(secret) > 200:
        return None
    return parts[1]


class KeyCache:
    """Verified keys (and whether any key was ever created) remembered for `ttl_s` seconds."""

    def __init__(
        self, ttl_s: float, *, capacity: int = 10_000, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.ttl_s = ttl_s
        self._keys: LRU[str, tuple[Principal | None]] = LRU(
            capacity=capacity, ttl_s=ttl_s, clock=clock
        )
        self._any: LRU[str, bool] = LRU(capacity=1, ttl_s=ttl_s, clock=clock)

    def authenticate(self, session_factory: sessionmaker[Session], secret: str) -> Principal | None:
        """The principal of `secret`, or None for an unknown, malformed or revoked key."""
        prefix = _split(secret)
        if prefix is None:
            return None
        digest = hash_key(secret)
        cached = self._keys.get(digest)
        if cached is not None:
            return cached[0]
        principal = self._lookup(session_factory, prefix, digest)
        self._keys.put(digest, (principal,))
        return principal

    def any_key(self, session_factory: sessionmaker[Session]) -> bool:
        """Whether any key was ever created (cached like keys)."""
        cached = self._any.get(_ANY)
        if cached is not None:
            return cached
        with session_factory() as session:
            return self._any.put(_ANY, any_key_created(session))

    def fresh(self, secret: str | None) -> bool:
        """Whether `any_key` and `authenticate(secret)` would answer without the database."""
        if _ANY not in self._any:
            return False
        return secret is None or hash_key(secret) in self._keys

    def clear(self) -> None:
        """Forget everything (after creating or revoking keys in this process)."""
        self._keys.clear()
        self._any.clear()

    @staticmethod
    def _lookup(
        session_factory: sessionmaker[Session], prefix: str, digest: str
    ) -> Principal | None:
        with session_factory() as session:
            rows = session.execute(
                sa.select(ApiKey).where(ApiKey.prefix == prefix, ApiKey.revoked_at.is_(None))
            ).scalars()
            for row in rows:
                if hmac.compare_digest(row.key_hash, digest):
                    return Principal(
                        key_id=row.id,
                        name=row.name,
                        prefix=row.prefix,
                        role=Role(row.role),
                        robot_ids=frozenset(row.robot_ids or []),
                    )
        return None
