"""The base of every request body's model: unknown fields are named, with the closest valid one.

Pydantic's own message for a field a model forbids is "Extra inputs are not permitted", without
the valid names. A :class:`RequestModel` answers instead `unknown field 'position' (did you mean
'pose'?); valid: id, pose, size` (`core.suggest`), the unknown names in its context (`fields`).
The check wraps the model's validation, so it sees the body after the model's own "before"
validators (an unwrapped envelope, a list read as fields) and names only the keys pydantic found
unknown at this level; errors of nested models are their own.
"""

from __future__ import annotations

from typing import Any

from pydantic import (
    BaseModel,
    ConfigDict,
    ModelWrapValidatorHandler,
    ValidationError,
    model_validator,
)
from pydantic_core import PydanticCustomError

from trajcache.core.suggest import unknown_message

__all__ = ["UNKNOWN_FIELD", "RequestModel"]

UNKNOWN_FIELD = "unknown_field"  # the error type of an unknown field


class RequestModel(BaseModel):
    """A request body (or part of one): unknown fields are refused, each named."""

    model_config = ConfigDict(extra="forbid")

    @model_validator(mode="wrap")
    @classmethod
    def _name_unknown_fields(cls, data: Any, handler: ModelWrapValidatorHandler[Any]) -> Any:
        try:
            return handler(data)
        except ValidationError as exc:
            unknown = [
                str(e["loc"][0])
                for e in exc.errors()
                if e["type"] == "extra_forbidden" and len(e["loc"]) == 1
            ]
            if not unknown:
                raise
            valid = [field.alias or name for name, field in cls.model_fields.items()]
            message = unknown_message("field", unknown, valid)
            context = {"message": message, "fields": unknown}
            raise PydanticCustomError(UNKNOWN_FIELD, "{message}", context) from None
