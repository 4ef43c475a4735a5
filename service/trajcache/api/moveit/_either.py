"""Routes that read a native body or a MoveIt service request, JSON or YAML, on one path.

The two are told apart by the MoveIt message's own top-level keys (no native body has them),
then validated as that message alone, so a 422 names the fields of the form that was meant.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, TypeVar

import pydantic_core
from fastapi import Response
from pydantic import BaseModel

from trajcache.api.moveit._body import RawBody, inlined_schema, read_document, validated

_Native = TypeVar("_Native", bound=BaseModel)
_MoveIt = TypeVar("_MoveIt", bound=BaseModel)


def either_body(
    native: type[BaseModel],
    moveit: type[BaseModel],
    examples: dict[str, Any],
    moveit_example: dict[str, Any],
) -> dict[str, Any]:
    """The route's `openapi_extra`: a body of either form, JSON (with `examples`) or YAML (with
    the MoveIt example), since a body parsed by hand is not in the generated document."""
    schema = {"oneOf": [inlined_schema(native), inlined_schema(moveit)]}
    return {
        "requestBody": {
            "required": True,
            "content": {  # a YAML body is read into the same document as a JSON one
                "application/json": {"schema": schema, "examples": examples},
                "application/yaml": {"schema": schema, "example": moveit_example},
            },
        }
    }


def answer_either(
    body: RawBody,
    *,
    native: type[_Native],
    native_fn: Callable[[_Native], dict[str, Any]],
    moveit: type[_MoveIt],
    moveit_keys: tuple[str, ...],
    moveit_fn: Callable[[_MoveIt, float], dict[str, Any]],
) -> Response:
    """The JSON answer to `body`: `moveit_fn(message, began)` when the document has any of
    `moveit_keys`, else `native_fn(native body)`; a malformed body is a 422."""
    began = time.perf_counter()
    document = read_document(body.media_type, body.data)
    if isinstance(document, dict) and any(key in document for key in moveit_keys):
        content = moveit_fn(validated(moveit, document), began)
    else:
        content = native_fn(validated(native, document))
    return Response(pydantic_core.to_json(content), media_type="application/json")
