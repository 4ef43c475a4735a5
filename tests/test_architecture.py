"""The package's layering, read from its import graph (imports inside functions count too).

- no module imports itself back through others (no cycles);
- the package's layers (`LAYERS`) and the services' concepts (`SERVICE_LAYERS`) each hold one
  order: a module imports from its own layer and the layers below, never from one above nor from
  a peer of its rank; every module lies in a layer, so a new package must be given its place;
- `api/` reaches the database only through `services/`;
- what happens after an answer has one home, `services/bookkeeping/`: its metrics are the only
  ones (no other module imports the Prometheus client but the route that serves them), and
  everything else counts in them through the bookkeeping (`outcomes`, `refusals`);
- geometry's stages import only from their own stage and earlier ones;
- no function outside numba's kernels takes more than eight parameters.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

from tests.imports import Graph, find_cycle, find_cycles, import_graph

PACKAGE = "trajcache"

# The package's layers, bottom first. Names on one line are peers: they import none of each other.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("core",),  # settings, LRU, request models
    ("geometry",),  # model → scene → collision → validation
    ("timing", "cache", "planning"),
    ("reference",),  # the reference robot and its workloads
    ("db",),  # tables, sessions, and the stored planning sources
    ("jobs",),  # worker pool, Celery
    ("services",),
    ("api", "dashboard"),
    ("main",),  # the app
    ("cli",),
)
# The services' concepts (sub-packages and top modules of services/), bottom first, as LAYERS.
SERVICE_LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "quality"),  # quality: a trajectory's, which the catalog stores and answers carry
    ("catalog",),
    ("bookkeeping",),  # what happens after an answer: records, rejections, quality, metrics
    ("context",),  # holds the catalog's caches and the bookkeeping
    ("robot_model", "stats"),
    ("ik",),
    ("plan",),
    ("cartesian", "seeding", "maintenance", "view"),
    ("background",),
)
FORBIDDEN = [("api", ("db",))]  # (importing layer, layers it must not import though below)
BOOKKEEPING = f"{PACKAGE}.services.bookkeeping"
METRICS = f"{BOOKKEEPING}.metrics"  # every metric of the service
METRICS_ROUTE = f"{PACKAGE}.api.prometheus"  # serves them at GET /metrics


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


def rank(module: str, prefix: str, layers: tuple[tuple[str, ...], ...]) -> tuple[int, str] | None:
    """The rank of the layer below `prefix` that `module` lies in, and the layer's name; None
    for a module outside `prefix` or `prefix` itself; (-1, name) for a layer not in `layers`."""
    head = prefix + "."
    if not module.startswith(head):
        return None
    name = module[len(head) :].split(".", 1)[0]
    return next(((k, name) for k, peers in enumerate(layers) if name in peers), (-1, name))


def unplaced(graph: Graph, prefix: str, layers: tuple[tuple[str, ...], ...]) -> list[str]:
    """The layers of `prefix`'s modules that `layers` does not place."""
    ranks = (rank(module, prefix, layers) for module in graph)
    return sorted({r[1] for r in ranks if r is not None and r[0] < 0})


def upward(graph: Graph, prefix: str, layers: tuple[tuple[str, ...], ...]) -> list[str]:
    """Imports from a lower layer into a higher one, or into a peer of the same rank."""
    found = []
    for module, targets in graph.items():
        here = rank(module, prefix, layers)
        for target in targets:
            there = rank(target, prefix, layers)
            if here is None or there is None or here[1] == there[1] or min(here[0], there[0]) < 0:
                continue
            if there[0] >= here[0]:
                found.append(f"{module} -> {target}")
    return sorted(found)


def test_layer_finder_finds_upward_and_sideways_imports() -> None:
    layers = (("core",), ("cache", "planning"), ("api",))
    toy = {
        "trajcache.core.config": {"trajcache.planning.options"},  # up
        "trajcache.cache.index": {"trajcache.planning.run", "trajcache.core.lru"},  # sideways
        "trajcache.api.routes": {"trajcache.cache.index", "trajcache.api.deps", "trajcache"},
        "trajcache.stray": set(),
    }
    assert upward(toy, PACKAGE, layers) == [
        "trajcache.cache.index -> trajcache.planning.run",
        "trajcache.core.config -> trajcache.planning.options",
    ]
    assert unplaced(toy, PACKAGE, layers) == ["stray"]


def test_every_module_lies_in_a_layer(graph: Graph) -> None:
    assert unplaced(graph, PACKAGE, LAYERS) == []
    assert unplaced(graph, f"{PACKAGE}.services", SERVICE_LAYERS) == []


def test_imports_point_down_the_layers(graph: Graph) -> None:
    assert upward(graph, PACKAGE, LAYERS) == []


def test_services_concepts_import_down_their_order(graph: Graph) -> None:
    assert upward(graph, f"{PACKAGE}.services", SERVICE_LAYERS) == []


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


def metrics_reached(graph: Graph) -> list[str]:
    """Modules outside the bookkeeping, but the metrics' route, that import the metrics."""
    return sorted(
        module
        for module, targets in graph.items()
        if METRICS in targets
        and not _in(module, "services.bookkeeping")
        and module != METRICS_ROUTE
    )


def importers_of(package: str, library: str) -> list[str]:
    """The modules of `package` that import `library` (or a module of it), anywhere in them."""
    root = Path(importlib.import_module(package).__file__ or "").parent
    found = []
    for path in sorted(root.rglob("*.py")):
        names = _absolute_imports(ast.parse(path.read_text(encoding="utf-8")))
        if any(name == library or name.startswith(library + ".") for name in names):
            parts = path.relative_to(root).with_suffix("").parts
            parts = parts[:-1] if parts[-1] == "__init__" else parts
            found.append(".".join((package, *parts)))
    return found


def _absolute_imports(tree: ast.AST) -> set[str]:
    """The modules `tree` imports by absolute name, anywhere in it."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names.add(node.module)
    return names


def test_metrics_finder_finds_a_count_outside_the_bookkeeping() -> None:
    toy = {
        "trajcache.services.plan.answers": {METRICS, "trajcache.services.bookkeeping.outcomes"},
        "trajcache.services.bookkeeping.outcomes": {METRICS},
        METRICS_ROUTE: {METRICS},
    }
    assert metrics_reached(toy) == ["trajcache.services.plan.answers"]


def test_only_the_bookkeeping_counts_in_the_metrics(graph: Graph) -> None:
    assert metrics_reached(graph) == []


def test_the_metrics_have_one_home() -> None:
    assert sorted(importers_of(PACKAGE, "prometheus_client")) == [METRICS_ROUTE, METRICS]


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
