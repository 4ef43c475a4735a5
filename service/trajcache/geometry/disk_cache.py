"""Arrays that take seconds to build and depend only on content (a mesh's sphere tree, a link
pair's distance table), kept on disk under a digest of that content.

An entry is found only by the digest of everything it was built from, so it is never stale: a
changed mesh, joint or grid gives another digest. Files are written whole to a temporary name
and renamed, so concurrent processes never read half a file; a file that cannot be read or
written is built again, never trusted. The folder is the user's cache directory
(`TRAJCACHE_PLANNER_CACHE_DIR` overrides it; `off` keeps nothing on disk).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import overload

import numpy as np
import platformdirs

VERSION = b"1"  # bump when what an entry means changes


def digest(parts: Iterable[object]) -> str:
    """A digest of the parts (arrays by their bytes, shape and type; the rest by repr)."""
    h = hashlib.sha256(VERSION)
    for part in parts:
        if isinstance(part, np.ndarray):
            h.update(repr((part.dtype.str, part.shape)).encode())
            h.update(np.ascontiguousarray(part).tobytes())
        else:
            h.update(repr(part).encode())
        h.update(b"|")
    return h.hexdigest()


def _folder() -> Path | None:
    setting = os.environ.get("TRAJCACHE_PLANNER_CACHE_DIR", "")
    if setting.strip().lower() == "off":
        return None
    if setting:
        return Path(setting)
    return Path(platformdirs.user_cache_dir("trajcache", appauthor=False)) / "planner"


@overload
def cached_arrays(
    kind: str, key: str, build: Callable[[], dict[str, np.ndarray]]
) -> dict[str, np.ndarray]: ...


@overload
def cached_arrays(
    kind: str,
    key: str,
    build: Callable[[], dict[str, np.ndarray]],
    build_if: Callable[[], bool],
) -> dict[str, np.ndarray] | None: ...


def cached_arrays(
    kind: str,
    key: str,
    build: Callable[[], dict[str, np.ndarray]],
    build_if: Callable[[], bool] | None = None,
) -> dict[str, np.ndarray] | None:
    """The arrays stored under `kind` and `key`, else `build()`'s, stored for next time; None
    when they are not stored and `build_if()` says not to build them now."""
    folder = _folder()
    path = None if folder is None else folder / kind / f"{key}.npz"
    if path is not None and path.is_file():
        try:
            with np.load(path, allow_pickle=False) as stored:
                return {name: stored[name] for name in stored.files}
        except (OSError, ValueError):
            pass  # unreadable: built again below
    if build_if is not None and not build_if():
        return None
    arrays = build()
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".tmp", delete=False) as tmp:
                np.savez(tmp, **arrays)  # type: ignore[arg-type]
            os.replace(tmp.name, path)
        except OSError:
            pass  # a read-only or full disk only costs the next process the build
    return arrays
