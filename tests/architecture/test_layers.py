"""The layers of docs/architecture.md, read from the source: who may import whom, and no module
or package that imports another in a circle. Every import counts, those inside functions too."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

ROOT = Path(__file__).resolve().parents[2]
# Each package and the packages of ours it may import (docs/architecture.md).
MAY_IMPORT = {
    "contract": set(),
    "surrogate": set(),
    "migrations": set(),
    "client": {"contract"},
    "server": {"contract", "surrogate", "migrations"},
    "planner": {"client", "contract", "surrogate"},
    "cpkb": {"contract", "client", "surrogate", "migrations", "server", "planner"},
}
# Third-party packages a package of ours must not import (the tree search takes a BindingWorld).
FORBIDDEN = {"planner.search": {"pybullet"}}


def _modules() -> dict[str, Path]:
    """Every module of our packages by dotted name (a package by its own name)."""
    found = {}
    for package in MAY_IMPORT:
        for path in (ROOT / package).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join(parts)] = path
    return found


def _imported(module: str, path: Path) -> set[str]:
    """The dotted names `module` imports (for `from a import b`: `a.b`, which may be a name)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                package = module.split(".")
                if path.name != "__init__.py":
                    package.pop()
                package = package[: len(package) - node.level + 1]
                base = ".".join([*package, *([base] if base else [])])
            names.update(f"{base}.{alias.name}" for alias in node.names)
    return names


def _graph() -> tuple[nx.DiGraph, dict[str, set[str]]]:
    """Our modules and their imports of each other; every module's imported names besides."""
    modules = _modules()
    graph: nx.DiGraph = nx.DiGraph()
    graph.add_nodes_from(modules)
    imported = {}
    for module, path in modules.items():
        imported[module] = _imported(module, path)
        for name in imported[module]:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and name != module:
                graph.add_edge(module, name)
    return graph, imported


GRAPH, IMPORTED = _graph()


def _package(module: str) -> str:
    return module.split(".")[0]


def test_the_graph_sees_the_packages_imports() -> None:
    """A guard on the reading itself: known edges are found."""
    assert GRAPH.has_edge("server.surrogates.engine", "surrogate.models")
    assert GRAPH.has_edge("cpkb.cli.planning", "cpkb.embedded")  # an import inside a function
    assert GRAPH.has_edge("planner.search.samplers.cp_bo", "planner.search.samplers.base")


def test_each_package_imports_only_the_layers_below_it() -> None:
    crossings = sorted(
        f"{a} -> {b}"
        for a, b in GRAPH.edges
        if _package(a) != _package(b) and _package(b) not in MAY_IMPORT[_package(a)]
    )
    assert crossings == []


def test_no_package_imports_another_in_a_circle() -> None:
    packages = nx.DiGraph((_package(a), _package(b)) for a, b in GRAPH.edges)
    packages.remove_edges_from(nx.selfloop_edges(packages))
    assert list(nx.simple_cycles(packages)) == []


def test_no_module_imports_another_in_a_circle() -> None:
    circles = [sorted(c) for c in nx.strongly_connected_components(GRAPH) if len(c) > 1]
    assert circles == []


def test_forbidden_third_party_imports() -> None:
    found = sorted(
        f"{module} imports {name}"
        for module, names in IMPORTED.items()
        for prefix, banned in FORBIDDEN.items()
        if module == prefix or module.startswith(prefix + ".")
        for name in names
        if name.split(".")[0] in banned
    )
    assert found == []
