"""The import graph: no circles, and every import runs down the layers that
``wheelcal/__init__.py``'s docstring lists (lazy and TYPE_CHECKING imports included)."""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

import pytest

import wheelcal

ROOT = Path(wheelcal.__file__).parent


def _modules() -> dict[str, Path]:
    out = {}
    for path in ROOT.rglob("*.py"):
        parts = path.relative_to(ROOT.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _resolve(name: str, modules: dict[str, Path]) -> str:
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name


def import_graph() -> dict[str, set[str]]:
    """module → the wheelcal modules it imports, anywhere in its code."""
    modules = _modules()
    graph = defaultdict(set)
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package
                    for _ in range(node.level - 1):
                        up = up.rpartition(".")[0]
                    base = up + ("." + base if base else "")
                # ``from a.b import c``: c may be a module or a name in a.b
                targets = [f"{base}.{a.name}" for a in node.names]
            for target in targets:
                if target.split(".")[0] == "wheelcal":
                    found = _resolve(target, modules)
                    if found != name:
                        graph[name].add(found)
    return graph


def layers() -> dict[str, int]:
    """Top-level package → its layer, from the numbered list in the package docstring."""
    out = {}
    for number, names in re.findall(r"^\s+(\d+)\.\s+([a-z_, ]+?)\s{2,}", wheelcal.__doc__, re.M):
        for package in names.split(","):
            out[package.strip()] = int(number)
    return out


def _package(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_every_package_has_a_layer():
    modules = _modules()
    packages = {_package(m) for m in modules} - {""}
    assert packages == set(layers()), packages ^ set(layers())


def test_no_import_runs_up_or_sideways():
    layer = layers()
    wrong = []
    for module, imported in import_graph().items():
        for target in imported:
            a, b = _package(module), _package(target)
            if b == "" and target == "wheelcal":
                continue  # the root: __version__ only (checked below)
            if a == b or a == "":
                continue
            if layer[b] >= layer[a]:
                wrong.append(f"{module} (layer {layer[a]}) imports {target} (layer {layer[b]})")
    assert not wrong, "\n".join(sorted(wrong))


def test_the_root_is_imported_for_its_version_only():
    for path in _modules().values():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module == "wheelcal" and not node.level:
                assert [a.name for a in node.names] == ["__version__"], path


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in list(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circles():
    assert _cycles(import_graph()) == []


@pytest.mark.parametrize(
    "graph, circles",
    [
        ({"a": {"b"}, "b": {"c"}, "c": {"a"}}, [["a", "b", "c"]]),
        ({"a": {"b"}, "b": {"c"}, "c": set()}, []),
    ],
)
def test_the_circle_finder_finds_circles(graph, circles):
    assert _cycles(graph) == circles
