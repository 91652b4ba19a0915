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


def _front_names(path: Path) -> set[str]:
    """The names a package's ``__init__`` binds by ``from … import`` at its top level."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {
        alias.asname or alias.name
        for node in tree.body
        if isinstance(node, ast.ImportFrom)
        for alias in node.names
    }


def import_graph() -> dict[str, set[str]]:
    """module → the wheelcal modules it imports, anywhere in its code."""
    modules = _modules()
    fronts = {m: _front_names(p) for m, p in modules.items() if p.name == "__init__.py"}
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
                # ``from a.b import c``: c may be a module or a name in a.b — the
                # name when a.b's front binds it (the front's ``gyro_axle`` function
                # over its module ``gyro_axle``: the import gives the function)
                targets = [
                    base if a.name in fronts.get(base, ()) else f"{base}.{a.name}"
                    for a in node.names
                ]
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


#: (importing package, inner module of another package) pairs src may keep, each
#: with its reason.  Every other import from another package goes through a front:
#: the package's (or sub-package's) ``__init__``, or a top-level module.
INNER_IMPORTS_ALLOWED: dict[tuple[str, str], str] = {}


def _fronts(modules: dict[str, Path]) -> set[str]:
    return {m for m, p in modules.items() if p.name == "__init__.py" or m.count(".") == 1}


def inner_imports() -> dict[tuple[str, str], list[str]]:
    """(importing package, inner module of another package) → the modules importing it."""
    fronts = _fronts(_modules())
    out = defaultdict(list)
    for module, imported in import_graph().items():
        for target in imported:
            a, b = _package(module), _package(target)
            if a and b and a != b and target not in fronts:
                out[(a, target)].append(module)
    return out


def test_other_packages_import_only_fronts():
    found = inner_imports()
    wrong = [
        f"{', '.join(sorted(found[pair]))} imports {pair[1]} (use its package's front)"
        for pair in sorted(set(found) - set(INNER_IMPORTS_ALLOWED))
    ]
    assert not wrong, "\n".join(wrong)
    stale = sorted(set(INNER_IMPORTS_ALLOWED) - set(found))
    assert not stale, f"allowed but no longer imported: {stale}"


def _layer_claims(doc: str) -> tuple[int, dict[str, set[str]]] | None:
    """A package docstring's "Layer N (above ``a``, below ``b``, beside ``c``)"."""
    match = re.search(r"\bLayer (\d+)(?: \(([^)]*)\))?", doc)
    if match is None:
        return None
    claims, relation = defaultdict(set), None
    for word, name in re.findall(r"\b(above|below|beside)\b|``(\w+)``", match.group(2) or ""):
        relation = word or relation
        if name and relation:
            claims[relation].add(name)
    return int(match.group(1)), claims


def test_package_docstrings_agree_with_the_layer_list():
    layer = layers()
    wrong = []
    for module, path in _modules().items():
        if path.name != "__init__.py" or module.count(".") != 1:
            continue
        claims = _layer_claims(ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or "")
        if claims is None:
            continue
        number, relations = claims
        package = _package(module)
        if number != layer[package]:
            wrong.append(f"{package} says layer {number}, the list {layer[package]}")
        for relation, names in relations.items():
            for name in sorted(names):
                ok = {
                    "above": layer[name] < number,
                    "below": layer[name] > number,
                    "beside": layer[name] == number,
                }[relation]
                if not ok:
                    wrong.append(
                        f"{package} (layer {number}) says {relation} {name} ({layer[name]})"
                    )
    assert not wrong, "\n".join(wrong)


@pytest.mark.parametrize(
    "doc, claims",
    [
        (
            "Layer 3 (above ``a``, ``b`` and ``c``; below ``d``).",
            (3, {"above": {"a", "b", "c"}, "below": {"d"}}),
        ),
        ("Layer 1.  Pure numpy.", (1, {})),
        ("Layers: a → b", None),
    ],
)
def test_the_layer_claims_are_read(doc, claims):
    assert _layer_claims(doc) == claims
