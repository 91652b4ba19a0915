"""The spine of ``wheelcal calibrate``, traced from the code: which packages a calibration walks.

Simulates a bench recording (``wheelcal simulate``, its default preset and seed),
then runs ``wheelcal calibrate`` on it in this process under :func:`sys.setprofile`.
Every call into a wheelcal function is mapped to its package (the module's first
part below ``wheelcal``) and compared with the nearest wheelcal caller on the stack:
a call from one package into another is a *crossing*, downward when the callee's
layer (the numbered list in ``wheelcal/__init__.py``'s docstring) is lower, upward
when it is higher.  Module-level code (imports, which depend on what is already
imported) is not traced.

The *spine* is the longest chain of packages linked by crossings, from the command
line down (ties: the chain whose crossings carry more calls).  Prints the spine, the
crossings per pair of packages (calls, and the distinct functions called across),
and the counts of downward and upward crossings::

    python tools/draw_spine.py              # the report
    python tools/draw_spine.py --mermaid    # the Mermaid diagram (docs/guide/how-it-works.md)
    python tools/draw_spine.py --json       # everything, for tests/test_spine_picture.py

The diagram's edges carry the number of distinct functions called across (a
property of the code's paths, not of how many iterations a fit took).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import itertools
import json
import re
import sys
import tempfile
from collections import Counter, defaultdict
from pathlib import Path

#: The recording traced (``wheelcal simulate``'s default: a bench's free spin).
SIMULATE = ("simulate",)


def layers() -> dict[str, int]:
    """Top-level package → its layer, from the numbered list in ``wheelcal``'s docstring."""
    import wheelcal

    out = {}
    for number, names in re.findall(r"^\s+(\d+)\.\s+([a-z_, ]+?)\s{2,}", wheelcal.__doc__, re.M):
        for package in names.split(","):
            out[package.strip()] = int(number)
    return out


def _package(module: str | None) -> str | None:
    """``wheelcal.session.fit`` → ``session``; ``wheelcal.api`` → ``api``; else None."""
    if not module or not module.startswith("wheelcal."):
        return None  # outside wheelcal, or the root package (its lazy names only)
    return module.split(".")[1]


class Tracer:
    """A profile function: a stack of the packages of the Python frames being run."""

    def __init__(self) -> None:
        self.stack: list[str | None] = []  # per frame: its package (None: not wheelcal)
        self.module_depth = 0  # frames of module-level code on the stack (imports)
        self.calls: Counter[tuple[str, str]] = Counter()
        self.functions: dict[tuple[str, str], set[str]] = defaultdict(set)
        self.entered: Counter[str] = Counter()

    def __call__(self, frame, event, arg) -> None:
        """Note a crossing when a wheelcal function is called from another package."""
        if event == "call":
            code = frame.f_code
            module_level = code.co_name == "<module>"
            package = _package(frame.f_globals.get("__name__"))
            self.stack.append(package)
            if module_level:
                self.module_depth += 1
            if package is None or self.module_depth:
                return
            self.entered[package] += 1
            caller = next((p for p in reversed(self.stack[:-1]) if p is not None), None)
            if caller is not None and caller != package:
                self.calls[caller, package] += 1
                name = f"{frame.f_globals.get('__name__')}.{code.co_qualname}"
                self.functions[caller, package].add(name)
        elif event == "return":
            if self.stack:
                self.stack.pop()
            if frame.f_code.co_name == "<module>" and self.module_depth:
                self.module_depth -= 1


def trace_calibrate(folder: Path) -> Tracer:
    """Simulate a bench recording in ``folder``, then trace ``wheelcal calibrate`` on it."""
    from wheelcal.cli.main import main

    recording = folder / "bench.mcap"
    with contextlib.redirect_stdout(io.StringIO()):  # "wrote …": not the report's
        simulated = main([*SIMULATE, str(recording)])
    if simulated != 0:
        raise RuntimeError("wheelcal simulate failed")
    argv = ["calibrate", str(recording), "--out", str(folder / "out"), "--quiet"]
    tracer = Tracer()
    sys.setprofile(tracer)
    try:
        status = main(argv)
    finally:
        sys.setprofile(None)
    if status != 0:
        raise RuntimeError(f"wheelcal calibrate exited {status}")
    return tracer


def spine(calls: Counter, start: str = "cli") -> list[str]:
    """The longest chain of crossings from ``start`` (ties: more calls along it)."""
    out: dict[str, list[str]] = defaultdict(list)
    for a, b in calls:
        out[a].append(b)
    best: dict[str, tuple[int, int, list[str]]] = {}

    def longest(node: str, seen: frozenset) -> tuple[int, int, list[str]]:
        options = [(1, 0, [node])]
        for nxt in sorted(out[node]):
            if nxt in seen:
                continue
            length, weight, chain = longest(nxt, seen | {nxt})
            options.append((length + 1, weight + calls[node, nxt], [node, *chain]))
        return max(options, key=lambda x: (x[0], x[1]))

    best[start] = longest(start, frozenset({start}))
    return best[start][2]


def summary(tracer: Tracer) -> dict:
    """The traced crossings as plain data: the spine, each pair, the counts by direction."""
    layer = layers()
    pairs = []
    for (a, b), n in sorted(tracer.calls.items(), key=lambda kv: (-layer[kv[0][0]], kv[0])):
        direction = "down" if layer[b] < layer[a] else "up" if layer[b] > layer[a] else "sideways"
        pairs.append(
            {
                "from": a,
                "to": b,
                "direction": direction,
                "calls": n,
                "functions": len(tracer.functions[a, b]),
            }
        )
    counts = Counter()
    for p in pairs:
        counts[p["direction"]] += p["calls"]
    path = spine(tracer.calls)
    return {
        "spine": path,
        "layers": {p: layer[p] for p in sorted({x for q in pairs for x in (q["from"], q["to"])})},
        "pairs": pairs,
        "down": counts["down"],
        "up": counts["up"],
        "sideways": counts["sideways"],
        "mermaid": mermaid(path, pairs, layer),
    }


def mermaid(path: list[str], pairs: list[dict], layer: dict[str, int]) -> str:
    """A Mermaid flowchart: the spine's crossings thick, the others thin; layers in the labels.

    Each edge carries the number of distinct functions called across it.
    """
    on_spine = set(itertools.pairwise(path))
    nodes = sorted({x for p in pairs for x in (p["from"], p["to"])}, key=lambda n: (-layer[n], n))
    lines = ["flowchart TD"]
    for node in nodes:
        lines.append(f'    {node}["{node} · layer {layer[node]}"]')
    for p in pairs:
        arrow = "==>" if (p["from"], p["to"]) in on_spine else "-->"
        label = f"{p['functions']} fn" + (" ↑ UP" if p["direction"] == "up" else "")
        lines.append(f'    {p["from"]} {arrow}|"{label}"| {p["to"]}')
    return "\n".join(lines)


def report(data: dict) -> str:
    """The spine, the crossings, and the counts, in words."""
    path = " → ".join(data["spine"])
    lines = [f"spine of `wheelcal calibrate` (a simulated bench recording): {path}"]
    lines.append(f"{'from':>12} → {'to':<12} {'direction':<9} {'calls':>8} {'functions':>9}")
    for p in data["pairs"]:
        lines.append(
            f"{p['from']:>12} → {p['to']:<12} {p['direction']:<9} {p['calls']:8d} "
            f"{p['functions']:9d}"
        )
    lines.append(
        f"crossings between packages: {data['down']} downward, {data['up']} upward, "
        f"{data['sideways']} sideways (calls)"
    )
    return "\n".join(lines)


def main() -> int:
    """Trace, then print the report, the diagram or the JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mermaid", action="store_true", help="print the Mermaid diagram only")
    ap.add_argument("--json", action="store_true", help="print everything as JSON")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="wheelcal-spine-") as tmp:
        data = summary(trace_calibrate(Path(tmp)))
    if args.json:
        print(json.dumps(data, indent=2))
    elif args.mermaid:
        print(data["mermaid"])
    else:
        print(report(data))
    return 0


if __name__ == "__main__":
    sys.exit(main())
