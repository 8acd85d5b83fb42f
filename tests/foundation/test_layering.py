"""The project's import graph, read from the source with ast: no import cycle between modules or between folders,
and no import upwards through the layers drivers <- safety <- pipeline, motion <- calibration <- runtime.

Every import counts, also one inside a function (a lazy import is a dependency too); only imports under
`if TYPE_CHECKING:` do not, since they never run. pipeline and motion share a layer and import neither each other.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
LAYER = {"drivers": 0, "safety": 1, "pipeline": 2, "motion": 2, "calibration": 3, "runtime": 4}


def project_modules() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the six packages (a package is its __init__.py)."""
    out = {}
    for package in LAYER:
        for path in (REPO / package).rglob("*.py"):
            parts = path.relative_to(REPO).with_suffix("").parts
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imported_names(tree: ast.Module, package: str) -> list[str]:
    """Every dotted name the module imports (for `from a import b`: a.b, which may be a module or a name in a)."""
    skipped = {
        id(n)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and _is_type_checking(node.test)
        for n in ast.walk(ast.Module(node.body, []))
    }
    names = []
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parent, base] if base else parent)
            names += [f"{base}.{a.name}" for a in node.names]
    return names


def import_graph() -> tuple[dict[str, set[str]], dict[str, Path]]:
    modules = project_modules()

    def resolve(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets = {resolve(n) for n in _imported_names(ast.parse(path.read_text()), package)}
        graph[name] = {t for t in targets if t is not None and t != name}
    return graph, modules


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one node (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def folder_graph(graph: dict[str, set[str]], modules: dict[str, Path]) -> dict[str, set[str]]:
    """Folder -> folders its files import (a folder is its own files, not its subfolders')."""
    folder = {name: ".".join(path.relative_to(REPO).parent.parts) for name, path in modules.items()}
    out: dict[str, set[str]] = defaultdict(set)
    for name, targets in graph.items():
        out[folder[name]] |= {folder[t] for t in targets if folder[t] != folder[name]}
    return out


@pytest.fixture(scope="module")
def graph():
    return import_graph()


def test_the_graph_sees_the_imports_it_should(graph):
    edges, modules = graph
    assert len(modules) > 100
    assert "runtime.config" in edges["runtime.run.runner"]  # a top-level import
    assert "pipeline.perception.dinov2" in edges["pipeline.perception.features"]  # a lazy one, inside a function


def test_no_module_imports_itself_back(graph):
    edges, _ = graph
    assert cycles(edges) == []


def test_no_folder_imports_itself_back(graph):
    edges, modules = graph
    assert cycles(folder_graph(edges, modules)) == []


def test_no_import_goes_up_a_layer_or_across_one(graph):
    edges, _ = graph
    upward = sorted(
        f"{a} -> {b}"
        for a, targets in edges.items()
        for b in targets
        if (top_a := a.split(".")[0]) != (top_b := b.split(".")[0]) and LAYER[top_b] >= LAYER[top_a]
    )
    assert upward == []


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
