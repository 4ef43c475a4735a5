"""The body of every error answer."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from trajcache.api.schemas.common import examples


class FieldErrorOut(BaseModel):
    """One invalid field of a request."""

    loc: list[str | int] = Field(description="Where: `body`, `query` or `path`, then the field.")
    msg: str
    type: str


class ErrorOut(BaseModel):
    """Every error answer: a readable `detail`; request validation also lists the fields."""

    model_config = ConfigDict(
        json_schema_extra=examples(
            {
                "detail": "body.start[1]: Input should be a finite number",
                "errors": [
                    {
                        "loc": ["body", "start", 1],
                        "msg": "Input should be a finite number",
                        "type": "finite_number",
                    }
                ],
            }
        )
    )

    detail: str
    errors: list[FieldErrorOut] | None = Field(
        default=None, description="The invalid fields (first 10), on request validation errors."
    )
