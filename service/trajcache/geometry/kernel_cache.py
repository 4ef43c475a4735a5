"""numba's on-disk cache of the geometry kernels, stamped with every kernel source file.

numba stamps a cached function with its own source file only: a kernel whose helper in another
module changed (the slabs and primitives are inlined into the segment kernels, the hull climb
is the model's) would load the old machine code, as numba's documentation warns. For a
collision check that is a safety matter, so the kernels' cache locators stamp each kernel with
the hash of every kernel source file (`KERNEL_SOURCES`): a change to any of them compiles all
of them again. Other functions keep numba's own locators.

Importing this module installs the locators; the kernel modules import it before their kernels
are defined.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path
from typing import Any

from numba.core import caching
from numba.core.caching import InTreeCacheLocator, UserProvidedCacheLocator, UserWideCacheLocator

__all__ = ["KERNEL_SOURCES", "LOCATORS", "install", "is_kernel_source", "kernel_sources_stamp"]

_GEOMETRY = Path(__file__).resolve().parent
# The kernels and everything they compile in: the collision kernels, the model's and the
# compiled planner's (which inline the collision kernels).
KERNEL_SOURCES = (
    _GEOMETRY / "collision" / "compiled",
    _GEOMETRY / "model" / "kernels.py",
    _GEOMETRY.parent / "planning" / "compiled",
)


def _files(sources: tuple[Path, ...]) -> list[Path]:
    files: list[Path] = []
    for source in sources:
        files.extend(sorted(source.glob("*.py")) if source.is_dir() else [source])
    return files


def is_kernel_source(path: str | Path, sources: tuple[Path, ...] = KERNEL_SOURCES) -> bool:
    """Whether `path` is one of the kernel source files."""
    return Path(path).resolve() in set(_files(sources))


def kernel_sources_stamp(sources: tuple[Path, ...] = KERNEL_SOURCES) -> str:
    """SHA-256 of every kernel source file's name and content."""
    files = _files(sources)
    return _stamp(tuple((str(f), f.stat().st_mtime_ns, f.stat().st_size) for f in files))


@functools.lru_cache(maxsize=8)
def _stamp(files: tuple[tuple[str, int, int], ...]) -> str:
    digest = hashlib.sha256()
    for name, _, _ in files:  # mtime and size only key the memo: a file changed is hashed again
        path = Path(name)
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


class _KernelStamp:
    """A locator for the files of `sources` only, stamped with all of them."""

    sources: tuple[Path, ...] = KERNEL_SOURCES

    def get_source_stamp(self) -> Any:
        own = super().get_source_stamp()  # type: ignore[misc]
        return (own, kernel_sources_stamp(self.sources))

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> Any:
        if not is_kernel_source(py_file, cls.sources):
            return None
        return super().from_function(py_func, py_file)  # type: ignore[misc]


class KernelCacheLocator(_KernelStamp, InTreeCacheLocator):
    """The kernels' cache in their package's `__pycache__`, numba's default place."""


class UserKernelCacheLocator(_KernelStamp, UserProvidedCacheLocator):
    """The kernels' cache under `NUMBA_CACHE_DIR`, when it is set."""


class UserWideKernelCacheLocator(_KernelStamp, UserWideCacheLocator):
    """The kernels' cache in the user's cache directory, when the package's is not writable."""


# In numba's order: the user's directory if set, the package's, the user-wide one.
LOCATORS = (UserKernelCacheLocator, KernelCacheLocator, UserWideKernelCacheLocator)


def install() -> None:
    """Put the kernels' locators ahead of numba's own (once)."""
    impl = getattr(caching, "CacheImpl", None) or vars(caching)["_CacheImpl"]  # its older name
    locators = impl._locator_classes
    locators[:0] = [locator for locator in LOCATORS if locator not in locators]


install()
