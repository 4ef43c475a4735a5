"""Messages that name a mistaken name: the closest valid one, and the valid ones.

Every "unknown field / key / type / joint" message of the service is written here, so they read
alike: `unknown field 'position' (did you mean 'pose'?); valid: id, pose, size, type`. The closest
name is difflib's (`get_close_matches`, ratio ≥ 0.6), or a synonym the caller names (`cube` →
`box`), never a guess below that ratio.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping, Sequence

__all__ = ["closest", "listed", "unknown_message"]

_CUTOFF = 0.6
_LISTED = 30  # valid names listed at most; more end with "…"


def closest(
    name: str, valid: Iterable[str], *, synonyms: Mapping[str, str] | None = None
) -> str | None:
    """The valid name `name` was most likely meant to be, if any is close enough."""
    names = list(valid)
    meant = (synonyms or {}).get(name.strip().lower())
    if meant is not None and meant in names:
        return meant
    matches = difflib.get_close_matches(name, names, n=1, cutoff=_CUTOFF)
    if not matches:  # a case or separator slip: `Panda_Joint1`, `panda-joint1`
        folded = {_fold(n): n for n in names}
        return folded.get(_fold(name))
    return matches[0]


def listed(valid: Iterable[str]) -> str:
    """The valid names, comma-separated, at most the first 30 of them."""
    names = list(valid)
    text = ", ".join(names[:_LISTED])
    return text + (", …" if len(names) > _LISTED else "")


def unknown_message(
    what: str,
    unknown: Sequence[str],
    valid: Iterable[str],
    *,
    synonyms: Mapping[str, str] | None = None,
    list_valid: bool = True,
) -> str:
    """`unknown <what> 'x' (did you mean 'y'?); valid: a, b` for one or more unknown names."""
    names = list(valid)
    parts = []
    for name in unknown:
        meant = closest(name, names, synonyms=synonyms)
        parts.append(f"{name!r}" + (f" (did you mean {meant!r}?)" if meant else ""))
    plural = "s" if len(unknown) > 1 else ""
    text = f"unknown {what}{plural} {', '.join(parts)}"
    if list_valid and names:
        text += f"; valid: {listed(names)}"
    return text


def _fold(name: str) -> str:
    return name.lower().replace("-", "").replace("_", "").replace(" ", "")
