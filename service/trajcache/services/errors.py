"""Service-level errors; `trajcache.api.errors` maps each one to an HTTP status.

ServiceError
├── AuthenticationError    401  no API key, or an unknown or revoked one
├── PermissionDeniedError  403  the key's role or robot binding does not allow the request
├── NotFoundError          404  an unknown model, robot or trajectory
├── ConflictError          409  the request contradicts what is stored
│   └── SceneRequiredError   409  a plan for a robot with no scene, under require_scene
├── PayloadTooLargeError   413  a request exceeds a configured size limit
├── InvalidInputError      422  a value the service cannot use (geometry has its own errors)
└── UnavailableError       503  the database cannot be reached

Errors of the geometry layer (`trajcache.geometry.errors.GeometryError`) are reused as is (422).
"""

from __future__ import annotations

from trajcache.geometry.errors import GeometryError

__all__ = [
    "AuthenticationError",
    "ConflictError",
    "GeometryError",
    "InvalidInputError",
    "NotFoundError",
    "PayloadTooLargeError",
    "PermissionDeniedError",
    "SceneRequiredError",
    "ServiceError",
    "UnavailableError",
]


class ServiceError(Exception):
    """Base class of the errors a service function raises on purpose."""


class AuthenticationError(ServiceError):
    """No API key, or one that is unknown or revoked."""


class PermissionDeniedError(ServiceError):
    """A valid key whose role or robot binding does not allow the request."""


class NotFoundError(ServiceError):
    """The named model, robot or trajectory does not exist."""


class ConflictError(ServiceError):
    """The request contradicts stored state."""


class SceneRequiredError(ConflictError):
    """A plan for a robot that never uploaded a scene, refused under `require_scene`."""


class PayloadTooLargeError(ServiceError):
    """A request exceeds a configured size limit (the message names the limit)."""


class InvalidInputError(ServiceError):
    """A value the service cannot use (bad id, page size above the limit, ...)."""


class UnavailableError(ServiceError):
    """The database (or another backing service) cannot be reached."""


# What a client is told when the database cannot be reached: never its host, port or driver's
# words (those go to the log).
DATABASE_UNAVAILABLE = "the database is unavailable"
