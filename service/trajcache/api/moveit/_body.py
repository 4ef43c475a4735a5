"""A MotionPlanRequest body: JSON or YAML text, validated like any body (a 422 names the field).

YAML is read with PyYAML's safe loader (the C one when present): plain data only, no tags that
build objects. Aliases cost nothing here: every list the message reads is bounded.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Annotated, Any, TypeVar

import yaml
from fastapi import Depends, Request
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ValidationError

from trajcache.api.bounded import is_json_media, media_type, unsupported_media
from trajcache.api.moveit._messages import MotionPlanRequestIn

YAML_TYPES = frozenset({"application/yaml", "application/x-yaml", "text/yaml", "text/x-yaml"})
_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_Model = TypeVar("_Model", bound=BaseModel)


def is_supported(media_type: str) -> bool:
    """Whether a body of this media type (lower case, no parameters) is read."""
    return is_json_media(media_type) or media_type in YAML_TYPES


@dataclass(frozen=True)
class RawBody:
    """A request body and its media type (lower case, without parameters)."""

    media_type: str
    data: bytes


async def read_raw_body(request: Request) -> RawBody:
    """The body (bounded by max_body_bytes while read); it is parsed in the worker thread."""
    media = media_type(request)
    if not is_supported(media):
        raise unsupported_media(media, "application/json or application/yaml")
    return RawBody(media, await request.body())


RawBodyDep = Annotated[RawBody, Depends(read_raw_body)]


def parse_motion_plan_request(media_type: str, data: bytes) -> MotionPlanRequestIn:
    """The request in `data`; RequestValidationError (422) names what is wrong."""
    return validated(MotionPlanRequestIn, read_document(media_type, data))


def validated(message: type[_Model], document: Any) -> _Model:
    """`document` read as `message`; RequestValidationError (422) names what is wrong."""
    try:
        return message.model_validate(document)
    except ValidationError as exc:
        errors = [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_url=False)]
        raise RequestValidationError(errors) from None


def inlined_schema(message: type[BaseModel]) -> dict[str, Any]:
    """The JSON schema of `message` with its nested messages inlined: a body parsed by hand has
    no components in the OpenAPI document."""
    schema = message.model_json_schema()
    return _inlined(schema, schema.get("$defs", {}))


def _inlined(node: Any, defs: dict[str, Any]) -> Any:
    """A JSON schema with each `#/$defs/...` reference replaced by its definition: the nested
    messages are not in the OpenAPI document's components (this body is parsed by hand)."""
    if isinstance(node, list):
        return [_inlined(item, defs) for item in node]
    if not isinstance(node, dict):
        return node
    ref = node.get("$ref")
    if isinstance(ref, str) and ref.startswith("#/$defs/"):
        rest = {k: v for k, v in node.items() if k != "$ref"}
        return _inlined({**defs[ref.removeprefix("#/$defs/")], **rest}, defs)
    return {k: _inlined(v, defs) for k, v in node.items() if k != "$defs"}


def read_document(media_type: str, data: bytes) -> Any:
    """The JSON or YAML document in `data`; RequestValidationError (422) when it is neither."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise _invalid("the body is not UTF-8 text") from None
    try:
        if media_type in YAML_TYPES:
            return yaml.load(text, Loader=_LOADER)  # a safe loader: plain data only
        return json.loads(text)
    except yaml.YAMLError as exc:
        raise _invalid(f"invalid YAML: {' '.join(str(exc).split())}") from None
    except json.JSONDecodeError as exc:
        raise _invalid(f"invalid JSON: {exc}") from None
    except RecursionError:
        raise _invalid("the body nests too deeply") from None


def _invalid(message: str) -> RequestValidationError:
    return RequestValidationError([{"type": "body_invalid", "loc": ("body",), "msg": message}])
