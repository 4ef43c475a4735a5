"""What the schema modules share: field types and the OpenAPI example values they agree on."""

from __future__ import annotations

import re
from datetime import datetime
from typing import Annotated, Any

from pydantic import AfterValidator, BeforeValidator, Field
from pydantic_core import PydanticCustomError

from trajcache.services.catalog.robots import ROBOT_ID_MAX_LENGTH, ROBOT_ID_PATTERN, check_robot_id
from trajcache.services.errors import InvalidInputError

_NUMBER = re.compile(r"\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*")


def _not_a_number(value: Any) -> Any:
    """Refuse the Unix times pydantic would read as datetimes: the schema says ISO 8601 text."""
    if isinstance(value, str) and _NUMBER.fullmatch(value):
        raise ValueError(f"{value!r} is a number, not an ISO 8601 date and time")
    return value


FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
ModelId = Annotated[str, Field(min_length=1, max_length=64)]
IsoDateTime = Annotated[datetime, BeforeValidator(_not_a_number)]  # ISO 8601 text only


def checked_robot_id(value: str) -> str:
    """`value` if it is a robot id; otherwise a validation error that names it."""
    try:
        return check_robot_id(value)
    except InvalidInputError as exc:
        raise PydanticCustomError("robot_id", "{reason}", {"reason": str(exc)}) from None


# The check is check_robot_id's (its message names the id); the schema states the same rule.
ROBOT_ID_SCHEMA: dict[str, Any] = {
    "pattern": ROBOT_ID_PATTERN,
    "minLength": 1,
    "maxLength": ROBOT_ID_MAX_LENGTH,
}
RobotId = Annotated[str, AfterValidator(checked_robot_id), Field(json_schema_extra=ROBOT_ID_SCHEMA)]

# Answers of the request examples, as the service gives them (OpenAPI examples of the responses).
MODEL_ID = "5158592d7f5559c728b6d23f76857a89890f358d7aa40994d9e2338ac93ec821"
SCENE_HASH = "08dd82870f84ed8b43d17f3baca4d6c55c6de216fbfee2996678642b82b81e4a"
WHEN = "2025-06-02T09:25:01.941173Z"


def examples(*values: dict[str, Any]) -> dict[str, Any]:
    """A model's `json_schema_extra` with these examples."""
    return {"examples": list(values)}
