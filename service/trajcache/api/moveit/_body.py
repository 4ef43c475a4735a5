"""A MotionPlanRequest body: JSON or YAML text, validated like any body (a 422 names the field).

YAML is read with PyYAML's safe loader (the C one when present): plain data only, no tags that
build objects. Aliases cost nothing here: every list the message reads is bounded.
"""

from __future__ import annotations

import json
from typing import Any

import yaml
from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from trajcache.api.bounded import is_json_media
from trajcache.api.moveit._messages import MotionPlanRequestIn

YAML_TYPES = frozenset({"application/yaml", "application/x-yaml", "text/yaml", "text/x-yaml"})
_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def is_supported(media_type: str) -> bool:
    """Whether a body of this media type (lower case, no parameters) is read."""
    return is_json_media(media_type) or media_type in YAML_TYPES


def parse_motion_plan_request(media_type: str, data: bytes) -> MotionPlanRequestIn:
    """The request in `data`; RequestValidationError (422) names what is wrong."""
    document = _document(media_type, data)
    try:
        return MotionPlanRequestIn.model_validate(document)
    except ValidationError as exc:
        errors = [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_url=False)]
        raise RequestValidationError(errors) from None


def _document(media_type: str, data: bytes) -> Any:
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
