"""Up-to-date checks: a session is skipped when its inputs and settings are unchanged.

The *run key* hashes the recording's bytes, the session options, what the run
produces (Rerun on/off) and the wheelcal version.  It is stored in the
calibration JSON; a re-run with the same key and all outputs present does no
work for that session.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
from pathlib import Path

from wheelcal import __version__
from wheelcal.session import SessionOptions


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file's contents."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def run_key(input_sha256: str, options: SessionOptions, produces: dict) -> str:
    """Hash of everything that determines a session's outputs."""
    payload = {
        "input": input_sha256,
        "options": _options_dict(options),
        "produces": produces,
        "version": __version__,
    }
    return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()


def _options_dict(options: SessionOptions) -> dict:
    """``dataclasses.asdict(options)``, once per options of a batch (~70 µs each time)."""
    try:
        return _options_dict_cached(options)
    except TypeError:  # an unhashable value among the options
        return dataclasses.asdict(options)


@functools.lru_cache(maxsize=8)
def _options_dict_cached(options: SessionOptions) -> dict:
    return dataclasses.asdict(options)  # only read (json.dumps): shared safely


def stored_run_key(calibration_path: Path) -> str | None:
    """The run key recorded in an existing calibration JSON (None if absent/unreadable)."""
    return run_key_of(read_document(calibration_path))


def read_document(calibration_path: Path) -> dict | None:
    """A calibration JSON's contents (None if absent, unreadable, or no regular file)."""
    from wheelcal.io import read_bounded

    try:
        document = json.loads(read_bounded(calibration_path, "calibration").decode("utf-8"))
    except (OSError, ValueError, RecursionError):  # InputError is a ValueError
        return None
    return document if isinstance(document, dict) else None


def run_key_of(document) -> str | None:
    """The run key recorded in a calibration document (None if it has none)."""
    if document is None:
        return None
    return document.get("provenance", {}).get("run_key")
