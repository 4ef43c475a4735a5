"""The import graph of a package, counting imports inside functions, and a cycle finder."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

Graph = dict[str, set[str]]


def import_graph(package: str) -> Graph:
    """Every module of `package` and the modules of `package` it imports, anywhere in it."""
    root = Path(importlib.import_module(package).__file__ or "").parent
    paths = {_module_name(package, root, p): p for p in root.rglob("*.py")}
    modules = set(paths)
    graph: Graph = {}
    for name, path in paths.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        is_package = path.name == "__init__.py"
        # A package's own name comes back from `from pkg import x` resolving to `pkg`.
        graph[name] = _imports(tree, name, is_package, package, modules) - {name}
    return graph


def find_cycle(graph: Graph) -> list[str] | None:
    """One cycle of `graph` (its modules in order), or None."""
    state: dict[str, int] = {}  # 1 on the current path, 2 done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt]
            if nxt not in state:
                found = visit(nxt)
                if found is not None:
                    return found
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found is not None:
                return found
    return None


def find_cycles(graph: Graph) -> list[list[str]]:
    """Cycles of `graph` until none is left, each found after cutting the last edge of the one
    before (so every cyclic tangle is named at least once)."""
    rest = {node: set(targets) for node, targets in graph.items()}
    found: list[list[str]] = []
    while (cycle := find_cycle(rest)) is not None:
        found.append(cycle)
        rest[cycle[-2]].discard(cycle[-1])
    return found


def _module_name(package: str, root: Path, path: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join((package, *parts))


def _resolve(name: str, package: str, modules: set[str]) -> str | None:
    """The module `name` is, or lies in (`a.b.c` for a name `c` imported from `a.b`)."""
    while name == package or name.startswith(package + "."):
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def _absolute(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    """The absolute module name of a (possibly relative) `from … import`."""
    if node.level == 0:
        return node.module or ""
    base = module if is_package else module.rpartition(".")[0]
    for _ in range(node.level - 1):
        base = base.rpartition(".")[0]
    return f"{base}.{node.module}" if node.module else base


def _imports(
    tree: ast.Module, module: str, is_package: bool, package: str, modules: set[str]
) -> set[str]:
    found: set[str] = set()
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            source = _absolute(node, module, is_package)
            names = [f"{source}.{alias.name}" for alias in node.names] + [source]
        for name in names:
            target = _resolve(name, package, modules)
            if target is not None:
                found.add(target)
    return found
