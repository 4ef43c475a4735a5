"""The package's layering, read from its import graph (imports inside functions count too).

- no module imports itself back through others (no cycles);
- `geometry/` imports nothing from `db/`, `api/` or `services/`;
- `cache/` and `planning/` import nothing from `db/` or `api/`;
- `api/` reaches the database only through `services/`;
- `core/` (settings, LRU, request models), the bottom layer, imports no other layer of the package;
- no function outside numba's kernels takes more than eight parameters.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

from tests.imports import Graph, find_cycle, find_cycles, import_graph

PACKAGE = "trajcache"

# (importing layer, layers it must not import)
FORBIDDEN = [
    ("geometry", ("db", "api", "services")),
    ("cache", ("db", "api")),
    ("planning", ("db", "api")),
    ("api", ("db",)),
    ("core", ("db", "geometry", "cache", "planning", "timing", "jobs", "services", "api", "cli")),
]


@pytest.fixture(scope="module")
def graph() -> Graph:
    return import_graph(PACKAGE)


def _in(module: str, layer: str) -> bool:
    name = f"{PACKAGE}.{layer}"
    return module == name or module.startswith(name + ".")


def violations(graph: Graph, layer: str, forbidden: tuple[str, ...]) -> list[str]:
    """The imports from `layer` into any of the `forbidden` layers, as `a -> b`."""
    return sorted(
        f"{module} -> {target}"
        for module, targets in graph.items()
        if _in(module, layer)
        for target in targets
        if any(_in(target, other) for other in forbidden)
    )


def test_graph_sees_module_and_function_level_imports(graph: Graph) -> None:
    assert len(graph) > 100
    assert "trajcache.services.plan.flow" in graph["trajcache.api.routes.plan"]
    # imported inside a function only
    assert "trajcache.jobs.celery_app" in graph["trajcache.jobs.pool"]


def test_finders_find_what_is_wrong() -> None:
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None
    assert find_cycles({"a": {"b"}, "b": {"a", "c"}, "c": {"b"}}) == [
        ["a", "b", "a"],
        ["b", "c", "b"],
    ]
    toy = {"trajcache.api.x": {"trajcache.db.models"}, "trajcache.db.models": set()}
    assert violations(toy, "api", ("db",)) == ["trajcache.api.x -> trajcache.db.models"]


def test_geometry_has_no_import_cycle(graph: Graph) -> None:
    geometry = {m: t for m, t in graph.items() if _in(m, "geometry")}
    cycle = find_cycle(geometry)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_no_import_cycles(graph: Graph) -> None:
    assert [" -> ".join(cycle) for cycle in find_cycles(graph)] == []


@pytest.mark.parametrize(("layer", "forbidden"), FORBIDDEN, ids=[f[0] for f in FORBIDDEN])
def test_layers_import_only_downwards(graph: Graph, layer: str, forbidden: tuple[str, ...]) -> None:
    assert violations(graph, layer, forbidden) == []


PIPELINE = ("model", "scene", "collision", "validation")  # geometry's stages, in order


def _stage(module: str) -> int | None:
    """Position in geometry's pipeline of the sub-package `module` lies in (None outside it)."""
    parts = module.split(".")
    if parts[:2] != [PACKAGE, "geometry"] or len(parts) < 3 or parts[2] not in PIPELINE:
        return None
    return PIPELINE.index(parts[2])


def backwards(graph: Graph) -> list[str]:
    """Imports from a later geometry stage: a stage imports only from itself or earlier ones."""
    return sorted(
        f"{module} -> {target}"
        for module, targets in graph.items()
        if (here := _stage(module)) is not None
        for target in targets
        if (there := _stage(target)) is not None and there > here
    )


def test_pipeline_finder_finds_a_backward_import() -> None:
    toy = {
        "trajcache.geometry.model.kinematics": {"trajcache.geometry.collision.compiled"},
        "trajcache.geometry.validation.certify": {"trajcache.geometry.model.motion"},
        "trajcache.geometry.warm": {"trajcache.geometry.validation.validator"},
    }
    assert backwards(toy) == [
        "trajcache.geometry.model.kinematics -> trajcache.geometry.collision.compiled"
    ]


def test_geometry_imports_follow_its_pipeline(graph: Graph) -> None:
    """model → scene → collision → validation: no stage imports from a later one."""
    assert backwards(graph) == []


MAX_PARAMETERS = 8  # more than this, and a request or options object is missing
JIT_DECORATORS = {"njit", "jit", "vectorize", "guvectorize", "cfunc"}  # numba's compilers


def _jitted(function: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    for decorator in function.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in JIT_DECORATORS:
            return True
    return False


def _parameter_count(function: ast.FunctionDef | ast.AsyncFunctionDef, in_class: bool) -> int:
    """Every parameter, `*args` and `**kwargs` included; a method's `self` or `cls` not."""
    a = function.args
    names = [p.arg for p in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    names += [p.arg for p in (a.vararg, a.kwarg) if p is not None]
    static = any(getattr(d, "id", "") == "staticmethod" for d in function.decorator_list)
    if in_class and not static and names[:1] in (["self"], ["cls"]):
        names = names[1:]
    return len(names)


def long_parameter_lists(module: str, source: str) -> list[str]:
    """`module.function (n)` for each function of `source`, numba's kernels aside, with more
    than `MAX_PARAMETERS` parameters."""
    found = []

    def visit(node: ast.AST, prefix: str, in_class: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                name = f"{prefix}.{child.name}"
                count = _parameter_count(child, in_class)
                if count > MAX_PARAMETERS and not _jitted(child):
                    found.append(f"{name} ({count})")
                visit(child, name, False)
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}.{child.name}", True)
            else:
                visit(child, prefix, in_class)

    visit(ast.parse(source), module, False)
    return found


def test_parameter_finder_counts_what_the_rule_counts() -> None:
    nine = ", ".join(f"p{i}" for i in range(9))
    source = (
        f"def wide({nine}): pass\n"
        "def starred(a, b, c, d, e, f, g, *args, **kwargs): pass\n"
        "def eight(a, b, c, d, e, f, g, h): pass\n"
        "class C:\n"
        "    def method(self, a, b, c, d, e, f, g, h): pass\n"
        "    @staticmethod\n"
        "    def static(self, a, b, c, d, e, f, g, h): pass\n"
        f"@numba.njit(cache=True)\ndef kernel({nine}): pass\n"
        f"@njit\ndef bare_kernel({nine}): pass\n"
    )
    assert long_parameter_lists("m", source) == ["m.wide (9)", "m.starred (9)", "m.C.static (9)"]


def test_no_function_outside_the_kernels_takes_more_than_eight_parameters() -> None:
    root = Path(importlib.import_module(PACKAGE).__file__ or "").parent
    found = []
    for path in sorted(root.rglob("*.py")):
        module = ".".join((PACKAGE, *path.relative_to(root).with_suffix("").parts))
        found += long_parameter_lists(module, path.read_text(encoding="utf-8"))
    assert found == []
