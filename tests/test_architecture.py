"""The package's layering, read from its import graph (imports inside functions count too).

- no module imports itself back through others (no cycles);
- `geometry/` imports nothing from `db/`, `api/` or `services/`;
- `cache/` and `planning/` import nothing from `db/` or `api/`;
- `api/` reaches the database only through `services/`;
- `core/` (settings, LRU, request models), the bottom layer, imports no other layer of the package.
"""

from __future__ import annotations

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
