"""The overwrite policy: who wrote an output that exists, from what, and may it be replaced.

One policy for every command that writes (docs/guide/outputs.md, "Overwriting"):

1. **Never onto an input**, even with ``--force``: an output that is one of
   the command's inputs — by name, through a symbolic link or a hard link
   (the same ``st_dev``/``st_ino``) — is refused.
2. **Never over what is not a regular file**, even with ``--force``: a
   folder, a device (``/dev/full``), a FIFO (also in
   :mod:`wheelcal.io.atomic`, which installs files).
3. **wheelcal's own output from the same input** is replaced, and the command
   says so.
4. **Anything else** — a recording, a user's file, an output wheelcal wrote
   from another input — is replaced only with ``--force``.

How wheelcal knows its own outputs: each carries an *origin*, a hash of the
real paths of the inputs it was made from (and, for ``simulate``, which reads
no file, of its options) — :func:`origin_of`:

* MCAP: the metadata record ``wheelcal.output`` (and the header's library
  ``wheelcal/<version>``);
* JSON: the top-level key ``wheelcal_output``;
* text (exports, Markdown): a line ``wheelcal-output: origin=<hex>``;
* PNG: the text chunk ``wheelcal-output``;
* Rerun ``.rrd``: wheelcal's application id in the file's header — no origin,
  so an ``.rrd`` wheelcal wrote is replaced with the outputs it goes with;
* CSV tables: no room for a mark — one *follows* the marked outputs written
  with it (a batch's ``report.md``, a study's ``study.json``): replaced when
  one of them is wheelcal's from the same input, else only with ``--force``.

Outputs written before wheelcal marked them: a calibration JSON (or a
report) whose ``source.file`` (``pipeline.file``) is the same input counts as
the same input; other unmarked files count as someone else's.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from wheelcal.io.file_kind import special_kind

#: The MCAP metadata record that marks wheelcal's outputs.
MARK_RECORD = "wheelcal.output"
#: The JSON key that marks wheelcal's outputs.
MARK_KEY = "wheelcal_output"
#: The text line (and PNG text key) that marks wheelcal's outputs.
MARK_TEXT = "wheelcal-output"
_MARK_LINE = re.compile(rb"wheelcal-output: origin=([0-9a-f]{8,64})")
_HEAD_BYTES = 64 << 10
_MCAP_MAGIC = b"\x89MCAP0\r\n"
_RRD_MAGIC = b"RRF2"
_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
_JSON_LIMIT = 64 << 20


def origin_of(inputs: Iterable[str | os.PathLike] = (), options: Mapping | None = None) -> str:
    """The origin of an output: its inputs' real paths (and ``options``), hashed."""
    payload = {
        "inputs": [os.path.realpath(p) for p in inputs],
        "options": dict(options or {}),
    }
    text = json.dumps(payload, sort_keys=True, default=str)
    return hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()[:32]


def output_mark(origin: str, inputs: Iterable[str | os.PathLike] = ()) -> dict[str, str]:
    """The mark's fields: ``origin`` and the ``inputs`` (real paths, as JSON text)."""
    return {"origin": origin, "inputs": json.dumps([os.path.realpath(p) for p in inputs])}


def mark_line(origin: str, inputs: Iterable[str | os.PathLike] = ()) -> str:
    """The mark as one line of text (for a comment in an export or Markdown)."""
    shown = ", ".join(str(p) for p in inputs)
    return f"{MARK_TEXT}: origin={origin}" + (f" (from {shown})" if shown else "")


@dataclass(frozen=True)
class Output:
    """One file a command is about to write, with the origin it will carry.

    ``follows``: the file cannot carry a mark (a CSV table); it is judged by
    the marked outputs claimed with it.
    """

    path: Path
    origin: str
    inputs: tuple[str, ...] = ()
    follows: bool = False


@dataclass(frozen=True)
class Existing:
    """What is at an output's path now.

    ``state``: ``absent``; ``input`` (one of the command's inputs); ``special``
    (not a regular file); ``ours`` (wheelcal's, from the same input); ``other``
    (wheelcal's, from another input); ``unknown`` (wheelcal's, its input not
    recorded: an ``.rrd``); ``foreign`` (not wheelcal's).
    """

    path: Path
    state: str
    detail: str = ""


class OutputRefusedError(ValueError):
    """Outputs the policy refuses to replace (the message names each and why)."""


def examine(
    path: str | os.PathLike, origin: str, inputs: Sequence[str | os.PathLike] = ()
) -> Existing:
    """What is at ``path``, judged against an output of ``origin`` made from ``inputs``."""
    path = Path(path)
    try:
        os.lstat(path)
    except FileNotFoundError:
        return Existing(path, "absent")
    except OSError as exc:
        return Existing(path, "foreign", f"cannot be examined ({exc.strerror or exc})")
    try:
        info = os.stat(path)
    except OSError:
        target = os.readlink(path) if path.is_symlink() else "?"
        return Existing(path, "foreign", f"is a symbolic link to {target}, which does not exist")
    for given in inputs:
        try:
            other = os.stat(given)
        except OSError:
            continue
        if (other.st_dev, other.st_ino) == (info.st_dev, info.st_ino):
            how = "" if os.path.abspath(given) == os.path.abspath(path) else f" ({given})"
            return Existing(path, "input", f"is an input of this command{how}")
    kind = special_kind(info.st_mode)
    if kind is not None:
        return Existing(path, "special", f"is {kind}, not a regular file")
    found = _read_mark(path)
    if found is None:
        return Existing(path, "foreign", _foreign_text(path))
    written_from, legacy_inputs = found
    if written_from == origin:
        return Existing(path, "ours", "wheelcal wrote it from the same input")
    if written_from is None:
        real = {os.path.realpath(p) for p in inputs}
        if legacy_inputs and real and {os.path.realpath(p) for p in legacy_inputs} <= real:
            return Existing(path, "ours", "wheelcal wrote it from the same input")
        if legacy_inputs is None:  # an .rrd: no room for an origin
            return Existing(path, "unknown", "wheelcal wrote it")
        return Existing(path, "other", "wheelcal wrote it, but it does not record from which input")
    return Existing(path, "other", f"wheelcal wrote it from another input{_inputs_of(path)}")


def claim_outputs(outputs: Sequence[Output], force: bool = False) -> list[str]:
    """Apply the policy to outputs about to be written together; the notes to show.

    Returns one note per file replaced (wheelcal's own from the same input, or
    anything with ``force``).  Raises :class:`OutputRefusedError` naming every
    output refused: one that is an input or not a regular file (even with
    ``force``), and without ``force`` every other existing file that is not
    wheelcal's from the same input.
    """
    seen = [(out, examine(out.path, out.origin, out.inputs)) for out in outputs]
    set_is_ours = any(e.state == "ours" for out, e in seen if not out.follows)
    set_is_other = any(e.state == "other" for out, e in seen if not out.follows)
    notes, refused = [], []
    for out, existing in seen:
        state = existing.state
        if state == "absent":
            continue
        if state in ("input", "special"):
            refused.append(
                f"{out.path} {existing.detail}: wheelcal never writes over it, even with --force"
            )
            continue
        if out.follows and state == "foreign" and set_is_ours:
            state, existing = (
                "ours",
                Existing(out.path, "ours", "wheelcal wrote it with the others"),
            )
        elif out.follows and state == "foreign" and set_is_other:
            existing = Existing(
                out.path, "other", "goes with outputs wheelcal wrote from another input"
            )
        if state in ("ours", "unknown"):
            notes.append(f"replacing {out.path} ({existing.detail})")
        elif force:
            notes.append(f"replacing {out.path} (--force: {existing.detail})")
        else:
            refused.append(
                f"{out.path} exists and {existing.detail}: not replaced (give --force to "
                "replace it)"
            )
    if refused:
        raise OutputRefusedError("; ".join(refused))
    return notes


def _foreign_text(path: Path) -> str:
    head = _head(path)
    if head.startswith(_MCAP_MAGIC):
        return "is a recording wheelcal did not write"
    return "wheelcal did not write it"


def _inputs_of(path: Path) -> str:
    """`` (<inputs>)`` as the mark of ``path`` records them, or ``""``."""
    inputs = _marked_inputs(path)
    return f" ({', '.join(inputs)})" if inputs else ""


def _head(path: Path, size: int = _HEAD_BYTES) -> bytes:
    try:
        with open(path, "rb") as stream:
            return stream.read(size)
    except OSError:
        return b""


def _read_mark(path: Path) -> tuple[str | None, list[str] | None] | None:
    """(origin or None, legacy inputs or None) when wheelcal wrote ``path``; None otherwise."""
    head = _head(path)
    if head.startswith(_MCAP_MAGIC):
        return _mcap_mark(path)
    if head.startswith(_RRD_MAGIC):
        return (None, None) if b"wheelcal" in head[:4096] else None
    if head.startswith(_PNG_MAGIC):
        origin = _png_text(head).get(MARK_TEXT)
        return (origin, []) if origin else None
    if head.lstrip()[:1] == b"{":
        return _json_mark(path)
    found = _MARK_LINE.search(head) or _MARK_LINE.search(_tail(path))
    return (found.group(1).decode(), []) if found else None


def _tail(path: Path, size: int = 4096) -> bytes:
    try:
        with open(path, "rb") as stream:
            stream.seek(max(0, os.fstat(stream.fileno()).st_size - size))
            return stream.read(size)
    except OSError:
        return b""


def _json_document(path: Path):
    from wheelcal.io.input_file import read_bounded

    try:
        return json.loads(read_bounded(path, "output", _JSON_LIMIT).decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        return None


def _json_mark(path: Path):
    doc = _json_document(path)
    if not isinstance(doc, dict):
        return None
    mark = doc.get(MARK_KEY)
    if isinstance(mark, dict) and isinstance(mark.get("origin"), str):
        return mark["origin"], []
    if not str(doc.get("format", "")).startswith("wheelcal."):
        return None
    legacy = []
    for block, key in (("source", "file"), ("pipeline", "file")):
        value = doc.get(block, {}).get(key) if isinstance(doc.get(block), dict) else None
        if isinstance(value, str):
            legacy.append(value)
    return None, legacy


def _marked_inputs(path: Path) -> list[str]:
    head = _head(path)
    if head.startswith(_MCAP_MAGIC):
        record = _mcap_metadata(path, MARK_RECORD)
        text = (record or {}).get("inputs", "[]")
    elif head.lstrip()[:1] == b"{":
        doc = _json_document(path)
        mark = doc.get(MARK_KEY) if isinstance(doc, dict) else None
        text = mark.get("inputs", "[]") if isinstance(mark, dict) else "[]"
    else:
        return []
    try:
        inputs = json.loads(text) if isinstance(text, str) else text
    except ValueError:
        return []
    return [str(p) for p in inputs] if isinstance(inputs, list) else []


def _png_text(head: bytes) -> dict[str, str]:
    """The PNG's tEXt chunks before its image data (in the first bytes read)."""
    out, at = {}, len(_PNG_MAGIC)
    while at + 8 <= len(head):
        length, kind = struct.unpack(">I4s", head[at : at + 8])
        body = head[at + 8 : at + 8 + length]
        if kind == b"IDAT" or len(body) < length:
            break
        if kind == b"tEXt" and b"\x00" in body:
            key, _, value = body.partition(b"\x00")
            out[key.decode("latin-1")] = value.decode("latin-1")
        at += 12 + length
    return out


def _mcap_mark(path: Path):
    """An MCAP written by wheelcal (its header's library): its ``wheelcal.output`` origin."""
    head = _head(path, 4096)
    at = len(_MCAP_MAGIC)
    try:
        op, _ = struct.unpack_from("<BQ", head, at)
        if op != 0x01:
            return None
        profile_len = struct.unpack_from("<I", head, at + 9)[0]
        library_at = at + 13 + profile_len
        library_len = struct.unpack_from("<I", head, library_at)[0]
        library = head[library_at + 4 : library_at + 4 + library_len].decode("utf-8")
    except (struct.error, UnicodeDecodeError):
        return None
    if not library.startswith("wheelcal"):
        return None
    record = _mcap_metadata(path, MARK_RECORD)
    origin = (record or {}).get("origin")
    return origin, (None if origin else [])


def _mcap_metadata(path: Path, name: str) -> dict[str, str] | None:
    """One metadata record of an MCAP, found through its summary's metadata index.

    Reads only the footer, the summary and that record (a recording of
    gigabytes costs a few reads); None when the file has no summary or no
    such record.
    """
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            footer_at = size - len(_MCAP_MAGIC) - 29
            if footer_at <= 0:
                return None
            f.seek(footer_at)
            footer = f.read(29)
            if footer[0] != 0x02:
                return None
            summary_start = struct.unpack_from("<Q", footer, 9)[0]
            if not 0 < summary_start < footer_at:
                return None
            f.seek(summary_start)
            summary = f.read(min(footer_at - summary_start, 16 << 20))
            at = 0
            while at + 9 <= len(summary):
                op, length = struct.unpack_from("<BQ", summary, at)
                if op == 0x0D:  # MetadataIndex: offset u64, length u64, name string
                    offset, record_len, name_len = struct.unpack_from("<QQI", summary, at + 9)
                    found = summary[at + 29 : at + 29 + name_len].decode("utf-8", "replace")
                    if found == name and record_len < (1 << 20):
                        f.seek(offset)
                        return _metadata_record(f.read(record_len))
                at += 9 + length
    except (OSError, struct.error, IndexError):
        return None
    return None


def _metadata_record(raw: bytes) -> dict[str, str] | None:
    """A Metadata record (opcode 0x0C: name, then a string map)."""
    try:
        if raw[0] != 0x0C:
            return None
        at = 9
        name_len = struct.unpack_from("<I", raw, at)[0]
        at += 4 + name_len
        map_len = struct.unpack_from("<I", raw, at)[0]
        at += 4
        stop, out = at + map_len, {}
        while at < stop:
            k_len = struct.unpack_from("<I", raw, at)[0]
            key = raw[at + 4 : at + 4 + k_len].decode("utf-8")
            at += 4 + k_len
            v_len = struct.unpack_from("<I", raw, at)[0]
            out[key] = raw[at + 4 : at + 4 + v_len].decode("utf-8")
            at += 4 + v_len
        return out
    except (IndexError, struct.error, UnicodeDecodeError):
        return None
