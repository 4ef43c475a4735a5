"""The message of a request body that fails validation: each mistake named, as it was meant.

Every request schema's errors go through :func:`readable_errors` (the API's handler of
validation errors, and the service's own validation of nested documents), so they read alike:

- a union (a state as a list, a map or a name) reports only the form the input came closest to:
  the branch whose error lies deepest in the input, its tag (pydantic's `list[float]`) dropped
  from the location; when no form got past its type, one line lists them all;
- an unknown field is named with the closest valid one (`core.request_model.RequestModel`), and
  located at it when it is the only one;
- a value outside a fixed set lists the set, and the closest member (`core.suggest`);
- a NaN or an infinity says that the number is not finite.
"""

from __future__ import annotations

import functools
import re
from collections import defaultdict
from collections.abc import Sequence
from typing import Any

from pydantic import BaseModel

from trajcache.core.request_model import UNKNOWN_FIELD
from trajcache.core.suggest import unknown_message

__all__ = ["readable_errors", "validation_message"]

Error = dict[str, Any]
_MAX_LISTED_ERRORS = 10
_PRIMITIVES = frozenset({"str", "int", "float", "bool", "list", "dict", "none", "bytes"})
_QUOTED = re.compile(r"'((?:[^'\\]|\\.)*)'")


def readable_errors(errors: Sequence[Any]) -> list[Error]:
    """The errors with each union reduced to its closest form and messages that name the value."""
    kept = [_at_unknown_field(dict(e)) for e in errors]
    while any(_tag_at(e.get("loc", ())) is not None for e in kept):
        kept = _closest_forms(kept)
    return [{**e, "msg": _message(e)} for e in kept]


def validation_message(errors: Sequence[Any]) -> str:
    """One readable line naming each invalid field, e.g. `body.states[0][1]: ...`."""
    parts = []
    for error in errors[:_MAX_LISTED_ERRORS]:
        where = _location(error.get("loc", ()))
        message = str(error.get("msg", "invalid value"))
        reason = (error.get("ctx") or {}).get("error")
        if error.get("type") == "json_invalid" and reason:
            message = f"{message} ({reason})"
        parts.append(f"{where}: {message}" if where else message)
    if len(errors) > _MAX_LISTED_ERRORS:
        parts.append(f"and {len(errors) - _MAX_LISTED_ERRORS} more error(s)")
    return "; ".join(parts) or "invalid request"


def _closest_forms(errors: list[Error]) -> list[Error]:
    """Each first union level resolved: the deepest branches kept, their tag dropped."""
    branches: dict[tuple[Any, ...], dict[str, list[Error]]] = defaultdict(dict)
    out: list[Error] = []
    for error in errors:
        loc = tuple(error.get("loc", ()))
        at = _tag_at(loc)
        if at is None:
            out.append(error)
        else:
            branches[loc[:at]].setdefault(loc[at], []).append(error)
    for prefix, forms in branches.items():
        depth = {tag: max(_depth(e, len(prefix)) for e in errs) for tag, errs in forms.items()}
        best = max(depth.values())
        chosen = [e for tag, errs in forms.items() if depth[tag] == best for e in errs]
        untagged = [{**e, "loc": (*prefix, *tuple(e["loc"])[len(prefix) + 1 :])} for e in chosen]
        if best == 0 and len(untagged) > 1:  # no form got past its type
            untagged = [_none_of(prefix, untagged)]
        out.extend(untagged)
    return out


def _depth(error: Error, tag_at: int) -> int:
    return len(error["loc"]) - tag_at - 1


def _at_unknown_field(error: Error) -> Error:
    """An unknown field's error located at the field, as pydantic's own are."""
    fields = (error.get("ctx") or {}).get("fields")
    if error.get("type") == UNKNOWN_FIELD and fields and len(fields) == 1:
        error["loc"] = (*tuple(error.get("loc", ())), fields[0])
    return error


def _none_of(prefix: tuple[Any, ...], errors: list[Error]) -> Error:
    forms = [str(e.get("msg", "")).removeprefix("Input should be ") for e in errors]
    unique = list(dict.fromkeys(forms))
    message = "Input should be one of: " + "; ".join(unique)
    given = errors[0].get("input")
    return {"type": "union_tag_invalid", "loc": prefix, "msg": message, "input": given}


def _tag_at(loc: Sequence[Any]) -> int | None:
    """The index of the first union tag in `loc` (pydantic names a union's branch there)."""
    for index, part in enumerate(loc):
        if isinstance(part, str) and _is_tag(part):
            return index
    return None


def _is_tag(part: str) -> bool:
    if "[" in part or part in _PRIMITIVES:
        return True
    if part.startswith(("constrained-", "function-", "lax-", "json-or-python")):
        return True
    return part[:1].isupper() and part in _model_names()


@functools.cache
def _model_names() -> frozenset[str]:
    """Names of the pydantic models loaded (a union of models tags its branches with them)."""
    seen: set[str] = set()
    todo: list[type[BaseModel]] = [BaseModel]
    while todo:
        for sub in todo.pop().__subclasses__():
            if sub.__name__ not in seen:
                seen.add(sub.__name__)
                todo.append(sub)
    return frozenset(seen)


def _message(error: Error) -> str:
    kind, message = error.get("type"), str(error.get("msg", "invalid value"))
    ctx, value = error.get("ctx") or {}, error.get("input")
    if kind == "finite_number":
        return f"{value!r} is not a finite number (NaN and infinities are refused)"
    if kind in ("literal_error", "enum") and isinstance(value, str) and "expected" in ctx:
        valid = [v.replace("\\'", "'") for v in _QUOTED.findall(str(ctx["expected"]))]
        if valid:
            return unknown_message("value", [value], valid)
    return message


def _location(loc: Sequence[Any]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out
