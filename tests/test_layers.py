"""The import graph: no circles, and every import runs down the layers that
``wheelcal/__init__.py``'s docstring lists (lazy and TYPE_CHECKING imports included);
other packages' modules reached through their fronts; package docstrings that agree
with the layer list.

Definitions, for the front test (:func:`inner_imports`):

* A *package* is any directory under ``src/wheelcal/`` with an ``__init__.py``:
  ``wheelcal.estimate``, ``wheelcal.estimate.joint`` and ``wheelcal.estimate.field``
  are three.  Its ``__init__`` is its *front*; its other modules are *inner*.  The
  root ``wheelcal`` is no front (it holds ``__version__`` and lazy names only); its
  own modules (``wheelcal.api``, ``wheelcal.runtime``) are layers of their own and
  count as fronts.
* A module belongs to the package whose directory holds it (an ``__init__`` to its
  own package).  It may import its own package's inner modules and any package's
  front.  An *inner import across packages* is an import, anywhere in the module
  (lazy, function-level and TYPE_CHECKING ones included), of an inner module of any
  other package — a sibling's (``estimate.field`` importing ``estimate.joint.fit``),
  a sub-package's or a parent's alike — or a lazy front's (``_LAZY``) name that
  resolves to one.  They are counted as distinct (importing module, inner module)
  pairs, and the only ones allowed are :data:`INNER_IMPORTS_ALLOWED`'s.
"""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

import pytest

import wheelcal

ROOT = Path(wheelcal.__file__).parent


def _modules(root: Path = ROOT) -> dict[str, Path]:
    out = {}
    for path in root.rglob("*.py"):
        parts = path.relative_to(root.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _resolve(name: str, modules: dict[str, Path]) -> str:
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name


def _lazy_front(tree: ast.Module) -> dict[str, str]:
    """A lazy front's names (PEP 562): name → the module its top-level ``_LAZY`` dict
    imports it from on first use (``"name": "module"`` or ``"name": ("module", "attr")``)."""
    out = {}
    for node in tree.body:
        if isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if any(isinstance(t, ast.Name) and t.id == "_LAZY" for t in targets):
                for name, where in ast.literal_eval(node.value).items():
                    out[name] = where if isinstance(where, str) else where[0]
    return out


def _front_names(path: Path) -> set[str]:
    """The names a package's ``__init__`` binds: by ``from … import`` at its top level,
    and a lazy front's ``_LAZY`` names."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {
        alias.asname or alias.name
        for node in tree.body
        if isinstance(node, ast.ImportFrom)
        for alias in node.names
    } | set(_lazy_front(tree))


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """module → the wheelcal modules it imports, anywhere in its code."""
    modules = _modules(root)
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


#: (importing module, inner module of another package) pairs src may keep, each with
#: the one-line reason it may; at most 15 (see the module docstring for the terms).
#: Every other import of another package's module goes through that package's front.
INNER_IMPORTS_ALLOWED: dict[tuple[str, str], str] = {}


def _package_of(module: str, modules: dict[str, Path]) -> str:
    """The package ``module`` belongs to: itself for an ``__init__``, else its folder's."""
    return module if modules[module].name == "__init__.py" else module.rpartition(".")[0]


def _is_inner(module: str, modules: dict[str, Path]) -> bool:
    """Whether ``module`` is a package's inner module: not a front, not the root's own."""
    return modules[module].name != "__init__.py" and module.count(".") > 1


def inner_imports(root: Path = ROOT) -> set[tuple[str, str]]:
    """(importing module, inner module of another package), lazy fronts' names included."""
    modules = _modules(root)
    imports = {
        (module, target) for module, targets in import_graph(root).items() for target in targets
    }
    for name, path in modules.items():
        if path.name == "__init__.py" and name != "wheelcal":
            lazy = _lazy_front(ast.parse(path.read_text(encoding="utf-8")))
            imports |= {(name, _resolve(where, modules)) for where in lazy.values()}
    return {
        (module, target)
        for module, target in imports
        if target in modules
        and _is_inner(target, modules)
        and _package_of(target, modules) != _package_of(module, modules)
    }


def test_other_packages_import_only_fronts():
    found = inner_imports()
    wrong = [
        f"{module} imports {target} (use {target.rpartition('.')[0]}'s front)"
        for module, target in sorted(found - set(INNER_IMPORTS_ALLOWED))
    ]
    assert not wrong, "\n".join(wrong)
    stale = sorted(set(INNER_IMPORTS_ALLOWED) - found)
    assert not stale, f"allowed but no longer imported: {stale}"
    assert len(INNER_IMPORTS_ALLOWED) <= 15
    for pair, reason in INNER_IMPORTS_ALLOWED.items():
        assert reason.strip() and "\n" not in reason, pair


_TREE = {
    "__init__.py": '_LAZY = {"Thing": ("wheelcal.a.x", "Thing")}\n',
    "top.py": "from wheelcal.a.x import f\n",
    "a/__init__.py": "from wheelcal.a.x import f\nfrom wheelcal.a.sub import g\n",
    "a/x.py": "from wheelcal.a import y\nfrom wheelcal.a.sub import g\nfrom wheelcal import top\n",
    "a/y.py": "from wheelcal.b import h\nfrom wheelcal.a.sub.s import g\n",
    "a/sub/__init__.py": "from wheelcal.a.sub.s import g\n",
    "a/sub/s.py": "from wheelcal.a.y import y\n",
    "b/__init__.py": 'from wheelcal.b.z import h\n\n_LAZY = {"w": "wheelcal.a.sub.s"}\n',
    "b/z.py": (
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from wheelcal.a.y import Y\n"
        "def h():\n    from wheelcal.a.x import f\n    import wheelcal.a.sub.s\n"
        "from wheelcal.a import sub, f\n"
    ),
}


def test_the_inner_import_finder_follows_the_definitions(tmp_path):
    for name, text in _TREE.items():
        path = tmp_path / "wheelcal" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    # not counted: a package's own inner modules (a → a.x, a.x → a.y), fronts (a.sub,
    # b, a's ``f``), the root's own modules (a.x → top) and the root's lazy names
    assert inner_imports(tmp_path / "wheelcal") == {
        ("wheelcal.top", "wheelcal.a.x"),  # the root's modules belong to no other package
        ("wheelcal.a.y", "wheelcal.a.sub.s"),  # a sub-package's inner module
        ("wheelcal.a.sub.s", "wheelcal.a.y"),  # the parent package's inner module
        ("wheelcal.b", "wheelcal.a.sub.s"),  # a lazy front's name
        ("wheelcal.b.z", "wheelcal.a.y"),  # under TYPE_CHECKING
        ("wheelcal.b.z", "wheelcal.a.x"),  # in a function
        ("wheelcal.b.z", "wheelcal.a.sub.s"),  # ``import wheelcal.a.sub.s``
    }


_LAYER_LINE = re.compile(r"^Layer (\d+)\b", re.M)
_LAYER_ANY = re.compile(r"\blayer (\d+)", re.I)
_RELATION = re.compile(r"\b(above|below|beside)\b((?:\s*(?:,|;|\band\b)?\s*``\w+``)+)")


def _layer_claims(doc: str) -> tuple[set[int], dict[str, set[str]]]:
    """What a docstring says of its layer: every number ("Layer 3", "layer 3") and every
    relation to a named package ("above ``a``, ``b`` and ``c``; below ``d``", "beside
    ``e``"), wherever in the docstring it stands."""
    claims = defaultdict(set)
    for relation, names in _RELATION.findall(doc):
        claims[relation] |= set(re.findall(r"``(\w+)``", names))
    return {int(n) for n in _LAYER_ANY.findall(doc)}, dict(claims)


def _docstring(path: Path) -> str:
    return ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""


def test_every_layer_states_its_number():
    """Each entry of the root's list — a top-level package's ``__init__`` or a top-level
    module — has a line "Layer N (…)" in its docstring."""
    modules = _modules()
    missing = [
        f"wheelcal.{name}'s docstring has no line 'Layer {number} (…)'"
        for name, number in sorted(layers().items())
        if not _LAYER_LINE.search(_docstring(modules[f"wheelcal.{name}"]))
    ]
    assert not missing, "\n".join(missing)


def test_package_docstrings_agree_with_the_layer_list():
    """Every package's front (sub-packages' too) and every top-level module: each layer
    number its docstring states is its top-level package's in the root's list, and each
    relation it states to a package in that list holds there."""
    layer = layers()
    wrong = []
    for module, path in sorted(_modules().items()):
        if module == "wheelcal" or (path.name != "__init__.py" and module.count(".") != 1):
            continue
        package = _package(module)
        number = layer[package]
        numbers, relations = _layer_claims(_docstring(path))
        wrong += [f"{module} says layer {n}, the list {number}" for n in sorted(numbers - {number})]
        for relation, names in sorted(relations.items()):
            for name in sorted(names & set(layer)):
                ok = {
                    "above": layer[name] < number,
                    "below": layer[name] > number,
                    "beside": layer[name] == number and name != package,
                }[relation]
                if not ok:
                    wrong.append(
                        f"{module} (layer {number}) says {relation} {name} ({layer[name]})"
                    )
    assert not wrong, "\n".join(wrong)


@pytest.mark.parametrize(
    "doc, claims",
    [
        (
            "Layer 3 (above ``a``, ``b`` and ``c``; below ``d``).",
            ({3}, {"above": {"a", "b", "c"}, "below": {"d"}}),
        ),
        ("Layer 1.  Pure numpy.", ({1}, {})),
        ("Layers: a → b", (set(), {})),
        ("Rerun files, written beside ``viz`` (it is layer 7).", ({7}, {"beside": {"viz"}})),
        ("The checks above.  ``io`` writes; ``b`` below.", (set(), {})),
    ],
)
def test_the_layer_claims_are_read(doc, claims):
    assert _layer_claims(doc) == claims
