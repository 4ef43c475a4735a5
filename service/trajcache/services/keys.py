"""API keys: created once (the secret is shown once), stored as a SHA-256 hash, revocable.

A key looks like `tc_<prefix>_<secret>`; the prefix (8 hex characters) finds the row and is safe
to show in listings and logs. Keys are 256-bit random values, so a plain SHA-256 of the whole key
is a sufficient hash (no salt or slow hash is needed for secrets nobody chose).

`KeyCache` remembers verified keys for a few seconds so a request costs no database round trip;
a revoked key therefore stops working on every replica within `auth_cache_ttl_s`.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
import threading
import time
from dataclasses import dataclass
from datetime import datetime
from enum import Enum

import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from trajcache.db.models import ApiKey, utcnow
from trajcache.services.errors import InvalidInputError, NotFoundError
from trajcache.services.robots import check_robot_id

KEY_PREFIX = "tc"
MAX_ROBOTS_PER_KEY = 1000


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
    """Revoke a key given by prefix (or id); revoking twice is harmless."""
    rows = list(session.execute(sa.select(ApiKey).where(ApiKey.prefix == key)).scalars())
    if not rows and key.isdigit():
        rows = list(session.execute(sa.select(ApiKey).where(ApiKey.id == int(key))).scalars())
    if not rows:
        raise NotFoundError(f"API key {key!r} not found")
    if len(rows) > 1:
        raise InvalidInputError(f"{key!r} names {len(rows)} keys; give the id")
    row = rows[0]
    if row.revoked_at is None:
        row.revoked_at = utcnow()
        session.commit()
    return _info(row)


def any_active_key(session: Session) -> bool:
    """Whether at least one unrevoked key exists."""
    found = session.scalar(sa.select(ApiKey.id).where(ApiKey.revoked_at.is_(None)).limit(1))
    return found is not None


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
    """Verified keys (and whether any key exists) remembered for `ttl_s` seconds."""

    def __init__(self, ttl_s: float) -> None:
        self.ttl_s = ttl_s
        self._lock = threading.Lock()
        self._keys: dict[str, tuple[Principal | None, float]] = {}
        self._any: tuple[bool, float] | None = None

    def authenticate(self, session_factory: sessionmaker[Session], secret: str) -> Principal | None:
        """The principal of `secret`, or None for an unknown, malformed or revoked key."""
        prefix = _split(secret)
        if prefix is None:
            return None
        digest = hash_key(secret)
        now = time.monotonic()
        with self._lock:
            cached = self._keys.get(digest)
        if cached is not None and now - cached[1] < self.ttl_s:
            return cached[0]
        principal = self._lookup(session_factory, prefix, digest)
        with self._lock:
            if len(self._keys) > 10_000:
                self._keys.clear()
            self._keys[digest] = (principal, now)
        return principal

    def any_key(self, session_factory: sessionmaker[Session]) -> bool:
        """Whether any active key exists (cached like keys)."""
        now = time.monotonic()
        with self._lock:
            cached = self._any
        if cached is not None and now - cached[1] < self.ttl_s:
            return cached[0]
        with session_factory() as session:
            found = any_active_key(session)
        with self._lock:
            self._any = (found, now)
        return found

    def fresh(self, secret: str | None) -> bool:
        """Whether `any_key` and `authenticate(secret)` would answer without the database."""
        now = time.monotonic()
        with self._lock:
            if self._any is None or now - self._any[1] >= self.ttl_s:
                return False
            if secret is None:
                return True
            cached = self._keys.get(hash_key(secret))
        return cached is not None and now - cached[1] < self.ttl_s

    def clear(self) -> None:
        """Forget everything (after creating or revoking keys in this process)."""
        with self._lock:
            self._keys.clear()
            self._any = None

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
