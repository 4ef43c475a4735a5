"""The package and the benchmarks stay readable: no module over 400 lines, and long functions
only where they are numeric kernels (numba compiles one function; splitting it would cost a call
per element). The benchmarks (bench/, not installed) have no kernels: none of their functions is
long."""

from __future__ import annotations

import ast
from pathlib import Path

import trajcache

PACKAGE_DIR = Path(trajcache.__file__).parent
BENCH_DIR = Path(__file__).resolve().parents[1] / "bench"
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 60
MAX_LONG_FUNCTIONS = 5
# The numeric kernels allowed to be long: (module path in the package, function).
KERNELS = {
    ("geometry/collision/compiled/scene_open.py", "_element_rows"),  # scene_open_kernel's loop
    ("geometry/collision/compiled/self_open.py", "self_open_kernel"),
    ("geometry/collision/compiled/state_rows.py", "state_rows_kernel"),
}


def module_lengths(root: Path) -> dict[str, int]:
    """Lines of each module under `root`, by its path relative to `root`."""
    return {
        str(path.relative_to(root)): len(path.read_text().splitlines())
        for path in sorted(root.rglob("*.py"))
    }


def long_functions(root: Path, limit: int) -> dict[tuple[str, str], int]:
    """Functions (methods and nested ones too) of more than `limit` lines, with their lengths."""
    found = {}
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > limit:
                    found[(str(path.relative_to(root)), node.name)] = length
    return found


def test_the_finders_find_what_is_too_long(tmp_path: Path) -> None:
    body = "\n".join(f"    x{i} = {i}" for i in range(70))
    source = f"def long() -> None:\n{body}\n\n\ndef short() -> None:\n    pass\n"
    (tmp_path / "big.py").write_text(source)
    assert module_lengths(tmp_path) == {"big.py": 75}
    assert long_functions(tmp_path, MAX_FUNCTION_LINES) == {("big.py", "long"): 71}


def test_no_module_is_over_400_lines() -> None:
    long = {path: n for path, n in module_lengths(PACKAGE_DIR).items() if n > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_only_numeric_kernels_are_long_functions() -> None:
    found = long_functions(PACKAGE_DIR, MAX_FUNCTION_LINES)
    assert set(found) <= KERNELS, f"functions over {MAX_FUNCTION_LINES} lines: {found}"
    assert len(found) <= MAX_LONG_FUNCTIONS


def test_no_benchmark_module_is_over_400_lines() -> None:
    lengths = module_lengths(BENCH_DIR)
    assert "load.py" in lengths and "harness/service.py" in lengths  # the harness is scanned too
    long = {path: n for path, n in lengths.items() if n > MAX_MODULE_LINES}
    assert not long, f"bench modules over {MAX_MODULE_LINES} lines: {long}"


def test_no_benchmark_function_is_long() -> None:
    found = long_functions(BENCH_DIR, MAX_FUNCTION_LINES)
    assert not found, f"bench functions over {MAX_FUNCTION_LINES} lines: {found}"
