"""Service-level errors; `trajcache.api.errors` maps each one to an HTTP status.

ServiceError
├── NotFoundError          404  an unknown model, robot or trajectory
├── ConflictError          409  the request contradicts what is stored
├── PayloadTooLargeError   413  a request exceeds a configured size limit
├── InvalidInputError      422  a value the service cannot use (geometry has its own errors)
└── UnavailableError       503  the database cannot be reached

Errors of the geometry layer (`trajcache.geometry.errors.GeometryError`) are reused as is (422).
"""

from __future__ import annotations

from trajcache.geometry.errors import GeometryError

__all__ = [
    "ConflictError",
    "GeometryError",
    "InvalidInputError",
    "NotFoundError",
    "PayloadTooLargeError",
    "ServiceError",
    "UnavailableError",
]


class ServiceError(Exception):
    """Base class of the errors a service function raises on purpose."""


class NotFoundError(ServiceError):
    """The named model, robot or trajectory does not exist."""


class ConflictError(ServiceError):
    """The request contradicts stored state."""


class PayloadTooLargeError(ServiceError):
    """A request exceeds a configured size limit (the message names the limit)."""


class InvalidInputError(ServiceError):
    """A value the service cannot use (bad id, page size above the limit, ...)."""


class UnavailableError(ServiceError):
    """The database (or another backing service) cannot be reached."""
