"""One numeric thread per planner worker.

Planner workers are processes, several to a machine, and their numeric work is small batches:
BLAS threads gain them nothing, while each one's OpenBLAS pool keeps a second core busy. So a
worker pins OpenBLAS, MKL, OpenMP and numba to one thread when it starts:

- the environment variables, which a library reads when it loads: they cover whatever the worker
  imports later, and the processes it starts;
- the OpenBLAS libraries already loaded (numpy's and scipy's, imported before the worker's first
  task, e.g. by the forkserver that forks it), through their own runtime setting, which is what
  `threadpoolctl` would call;
- numba's pool size, read again from the environment (its threads start on first parallel use).
"""

from __future__ import annotations

import ctypes
import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

ONE_THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
}
# OpenBLAS's runtime thread setting under the names its builds export (numpy's and scipy's
# wheels prefix it, the 64-bit interface adds a suffix).
_PREFIXES = ("openblas", "scipy_openblas")
_SUFFIXES = ("", "64_")


def pin_one_thread() -> None:
    """Limit this process's numeric libraries to one thread (loaded now or later)."""
    os.environ.update(ONE_THREAD_ENV)
    for _path, library in _loaded_openblas():
        setter = _function(library, "set_num_threads")
        if setter is not None:
            setter(1)
    config = sys.modules.get("numba.core.config")
    if config is not None:
        try:
            config.reload_config()
        except RuntimeError:  # its threads run already: use fewer of them
            import numba

            numba.set_num_threads(1)


def thread_counts() -> dict[str, int]:
    """Threads each loaded OpenBLAS library would use (by file name), and numba's pool size."""
    counts: dict[str, int] = {}
    for path, library in _loaded_openblas():
        getter = _function(library, "get_num_threads")
        if getter is not None:
            counts[f"openblas {path.name}"] = int(getter())
    config = sys.modules.get("numba.core.config")
    if config is not None:
        counts["numba"] = int(config.NUMBA_NUM_THREADS)
    return counts


def _loaded_openblas() -> Iterator[tuple[Path, ctypes.CDLL]]:
    """The OpenBLAS libraries mapped into this process (none where /proc is missing)."""
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return
    paths = {line.split()[-1] for line in maps.splitlines() if "openblas" in line}
    for path in sorted(paths):
        if path.startswith("/"):
            yield Path(path), ctypes.CDLL(path)  # already loaded: the same handle, no new copy


def _function(library: ctypes.CDLL, name: str) -> Callable[..., int] | None:
    """The library's `openblas_<name>` under whichever of its build's names it exports."""
    for prefix in _PREFIXES:
        for suffix in _SUFFIXES:
            function = getattr(library, f"{prefix}_{name}{suffix}", None)
            if function is not None:
                function.restype = ctypes.c_int
                return function
    return None


__all__ = ["ONE_THREAD_ENV", "pin_one_thread", "thread_counts"]
