"""Output stems for a batch: unique, stable, and the plain file name whenever it is unique.

Recordings from different folders often share a name (``day1/session-00.mcap``,
``day2/session-00.mcap``).  Every output of a session is named after its stem
(``<stem>.calibration.json``, ``<stem>.rrd``), so the stems must differ:

* a recording whose name (without ``.mcap``) is unique in the batch keeps it;
* recordings that share a name get the shortest suffix of their folder path
  that tells them apart, joined with ``__``: ``day1__session-00``,
  ``day2__session-00`` (``a__x__s`` / ``b__x__s`` when the nearest folders
  agree too).

The stem depends only on the set of inputs and on the resolved folder names
(not on the order, the working directory or how a path was spelled), so a
re-run finds its earlier outputs.  Adding a recording with a clashing name
renames the outputs of the one it clashes with — the only way both can keep
their files.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from pathlib import Path

from wheelcal.calibration import session_stem

SEPARATOR = "__"


def unique_stems(paths: Iterable[str | Path]) -> dict[str, str]:
    """``{path: stem}`` for the inputs of one batch (see the module docstring).

    Raises
    ------
    ValueError
        When two inputs are the same file (spelled differently), which no stem
        can tell apart.
    """
    paths = [str(p) for p in paths]
    resolved = {p: Path(p).resolve() for p in paths}
    seen: dict[Path, str] = {}
    for p in sorted(paths):
        if resolved[p] in seen:
            raise ValueError(f"{p} and {seen[resolved[p]]} are the same recording")
        seen[resolved[p]] = p
    folders = {p: _folders(resolved[p]) for p in paths}
    by_name: dict[str, list[str]] = defaultdict(list)
    for p in paths:
        by_name[session_stem(p)].append(p)
    depth = {p: 0 for p in paths}
    for group in by_name.values():
        for p in group if len(group) > 1 else ():
            others = [folders[q] for q in group if q != p]
            k = 1
            while k < len(folders[p]) and any(_tail(o, k) == _tail(folders[p], k) for o in others):
                k += 1
            depth[p] = k
    limit = max(len(f) for f in folders.values()) + 1
    while True:
        stems = {p: SEPARATOR.join([*_tail(folders[p], depth[p]), session_stem(p)]) for p in paths}
        taken: dict[str, list[str]] = defaultdict(list)
        for p, stem in stems.items():
            taken[stem].append(p)
        # A derived stem may equal another input's stem (a file named ``day1__s.mcap``, or
        # folder names holding ``__``): lengthen the derived ones until none is shared.
        clashing = [p for group in taken.values() if len(group) > 1 for p in group if depth[p]]
        if not clashing:
            return stems
        for p in clashing:
            depth[p] += 1
        if any(depth[p] > limit for p in clashing):
            raise ValueError(f"cannot give these inputs distinct output names: {sorted(clashing)}")


def _folders(path: Path) -> tuple[str, ...]:
    return tuple(part for part in path.parent.parts if part != path.anchor)


def _tail(folders: tuple[str, ...], k: int) -> tuple[str, ...]:
    return folders[-k:] if k else ()
