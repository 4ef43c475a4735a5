"""The kernels' on-disk cache is stamped with every kernel source file, so a change to a helper
in another module compiles the kernels that inline it again (numba alone would not)."""

from __future__ import annotations

import ast
import importlib
import inspect
import os
import subprocess
import sys
from pathlib import Path

import numba
import pytest
from numba.core.registry import CPUDispatcher

from trajcache.geometry import kernel_cache
from trajcache.geometry.kernel_cache import (
    KERNEL_SOURCES,
    LOCATORS,
    UserWideKernelCacheLocator,
    kernel_sources_stamp,
)

KERNEL_MODULES = [
    "trajcache.geometry.model.kernels",
    "trajcache.geometry.collision.compiled.primitives",
    "trajcache.geometry.collision.compiled.slabs",
    "trajcache.geometry.collision.compiled.scene_open",
    "trajcache.geometry.collision.compiled.self_open",
    "trajcache.geometry.collision.compiled.state_rows",
    "trajcache.geometry.collision.compiled.spheres",
    "trajcache.geometry.collision.compiled.gjk",
    "trajcache.geometry.collision.compiled.settle",
    "trajcache.planning.compiled.search",
]


def test_every_cached_kernel_is_stamped_with_all_kernel_sources() -> None:
    files = set()
    cached = 0
    for name in KERNEL_MODULES:
        module = importlib.import_module(name)
        for value in vars(module).values():
            if not isinstance(value, CPUDispatcher) or value.__module__ != name:
                continue
            assert value._cache is not None and value._cache._impl is not None, value
            locator = value._cache._impl._locator
            assert isinstance(locator, LOCATORS), value
            assert locator.get_source_stamp()[1] == kernel_sources_stamp()
            files.add(Path(module.__file__ or "").resolve())
            cached += 1
    assert cached >= 15
    sources = {p for s in KERNEL_SOURCES for p in (s.glob("*.py") if s.is_dir() else [s])}
    assert files == {p for p in sources if p.name != "__init__.py"}  # no kernel file left out


def test_the_stamp_changes_with_any_kernel_source(tmp_path: Path) -> None:
    for name in ("a.py", "b.py"):
        (tmp_path / name).write_text("x = 1\n")
    before = kernel_sources_stamp((tmp_path,))
    (tmp_path / "b.py").write_text("x = 2\n")
    assert kernel_sources_stamp((tmp_path,)) != before
    assert kernel_sources_stamp((tmp_path,)) == kernel_sources_stamp((tmp_path,))


HELPER = "import numba\n\n@numba.njit(cache=True, inline='always')\ndef helper():\n    return {}\n"
KERNEL = """\
import numba
from helper import helper

@numba.njit(cache=True)
def kernel():
    return helper()
"""
RUN = """\
import sys
from pathlib import Path
if sys.argv[1] == "stamped":
    from trajcache.geometry import kernel_cache
    from numba.core import caching

    class Toy(kernel_cache.KernelCacheLocator):
        sources = (Path.cwd() / "kernels",)

    impl = getattr(caching, "CacheImpl", None) or vars(caching)["_CacheImpl"]
    impl._locator_classes.insert(0, Toy)
sys.path.insert(0, str(Path.cwd() / "kernels"))
from kernel import kernel
print(kernel())
"""


def _run(where: Path, mode: str) -> int:
    env = {**os.environ, "NUMBA_CACHE_DIR": ""}
    out = subprocess.run(
        [sys.executable, "run.py", mode], cwd=where, env=env, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    return int(out.stdout.split()[-1])


def test_a_changed_helper_in_another_file_recompiles_the_kernel(tmp_path: Path) -> None:
    # With numba's own locators (`python run.py numba`, numba 0.68) the second run answers 1:
    # the kernel's file did not change, so its cache still holds the old helper.
    (tmp_path / "kernels").mkdir()
    (tmp_path / "run.py").write_text(RUN)
    (tmp_path / "kernels" / "kernel.py").write_text(KERNEL)
    (tmp_path / "kernels" / "helper.py").write_text(HELPER.format(1))
    assert _run(tmp_path, "stamped") == 1  # compiled and cached
    assert list((tmp_path / "kernels" / "__pycache__").glob("kernel.kernel-*.nbi"))
    (tmp_path / "kernels" / "helper.py").write_text(HELPER.format(2))
    assert _run(tmp_path, "stamped") == 2


def test_installing_twice_adds_the_locators_once_ahead_of_numba_s() -> None:
    kernel_cache.install()
    impl = getattr(numba.core.caching, "CacheImpl", None) or vars(numba.core.caching)["_CacheImpl"]
    locators = impl._locator_classes
    assert tuple(locators[: len(LOCATORS)]) == LOCATORS
    assert all(locators.count(locator) == 1 for locator in LOCATORS)


def test_the_user_wide_cache_is_stamped_too(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where the package's own `__pycache__` is not writable (an installed image), numba caches
    in the user's cache directory: stamped the same way."""
    from trajcache.geometry.model.kernels import hull_climb

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    py_file = inspect.getfile(hull_climb.py_func)
    locator = UserWideKernelCacheLocator.from_function(hull_climb.py_func, py_file)
    assert locator is not None and str(tmp_path) in locator.get_cache_path()
    assert locator.get_source_stamp()[1] == kernel_sources_stamp()
    assert UserWideKernelCacheLocator.from_function(_defined_in, __file__) is None  # not a kernel


def _defined_in(module_name: str, name: str) -> Path:
    """The file of the module that defines `name` as imported from `module_name` (a constant,
    which has no `__module__`, is taken as that module's own)."""
    value = getattr(importlib.import_module(module_name), name)
    home = importlib.import_module(getattr(value, "__module__", module_name))
    return Path(home.__file__ or "").resolve()


def test_the_kernels_compile_in_nothing_from_outside_the_stamped_files() -> None:
    """numba compiles in the functions and the globals a kernel uses: any module they come from
    must be stamped too (a type alias is not compiled in, nor is the locators' module)."""
    sources = {p for s in KERNEL_SOURCES for p in (s.glob("*.py") if s.is_dir() else [s])}
    type_only = {
        ("trajcache.geometry.model.shapes", "FloatArray"),
        ("trajcache.geometry", "kernel_cache"),
    }
    outside = []
    for path in sources:
        for node in ast.walk(ast.parse(path.read_text())):
            module = node.module if isinstance(node, ast.ImportFrom) else None
            if module is None or not module.startswith("trajcache"):
                continue
            for alias in node.names:
                if (module, alias.name) in type_only:
                    continue
                if _defined_in(module, alias.name) not in sources:
                    outside.append(f"{path.name}: {module}.{alias.name}")
    assert not outside, outside
