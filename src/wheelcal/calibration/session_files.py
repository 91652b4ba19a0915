"""A session's files: the view (``.rrd``), the closed loop's report and, last, the calibration JSON.

The one writer of a calibrated session's files (``wheelcal calibrate``,
``diagnose``, the batch and :meth:`~wheelcal.calibration.document.Calibration.write`
all write through :func:`write_session_files`).  The calibration JSON is
written last: it marks a complete session (the batch's up-to-date check).  If a
later file fails (a full disk), the ones this attempt wrote go too: none may
pass for a stale earlier result, nor for this run's.

The ``.rrd`` is drawn by :mod:`wheelcal.viz` — a layer above this one — so the
caller passes its writer in (``rrd_writer``, e.g. ``wheelcal.viz.write_session_rrd``).
A failed session's earlier outputs are renamed ``<stem>.<kind>.stale.<ext>``
(:func:`keep_as_stale`); :func:`session_outputs` lists what a session writes,
for the overwrite policy.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from wheelcal.session import SessionResult

#: Outputs of a session, renamed ``<stem>.<kind>.stale.<ext>`` when a re-run fails.
OUTPUT_SUFFIXES = (".calibration.json", ".diagnosis.json", ".rrd")

#: ``rrd_writer(path, session, durable, document) -> Path``: a session's Rerun view.
RrdWriter = Callable[..., Path]


@dataclass(frozen=True)
class WrittenFiles:
    """The files one session wrote (None: not written) and the seconds each step took."""

    calibration_path: str
    diagnosis_path: str | None = None
    rrd_path: str | None = None
    #: ``"rrd"`` (when written) and ``"write"`` (the diagnosis and the JSON), s.
    timings_s: dict[str, float] = field(default_factory=dict)


def session_stem(path: str | Path) -> str:
    """Output stem of a recording: its file name without ``.mcap``."""
    name = Path(path).name
    return name[: -len(".mcap")] if name.endswith(".mcap") else Path(path).stem


def write_session_files(
    session: SessionResult,
    document: dict,
    folder: str | Path,
    stem: str,
    rrd_writer: RrdWriter | None = None,
    diagnosis: bool = False,
    durable: bool = True,
) -> WrittenFiles:
    """Write a computed session's files into ``folder`` (module docstring).

    ``document`` is the session's calibration document (``calibration_dict``), which
    the JSON holds and the view's verdict reads.

    ``rrd_writer``: write ``<stem>.rrd`` with it (None: no view); ``diagnosis``:
    also ``<stem>.diagnosis.json`` when the session has the closed loop's report.
    ``durable=False`` skips the per-file fsyncs; the files are still written atomically.
    """
    from wheelcal.calibration.diagnosis_json import write_diagnosis
    from wheelcal.calibration.session_json import write_calibration

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    t1 = time.perf_counter()
    rrd_path = diagnosis_path = None
    written: list[Path] = []
    try:
        if rrd_writer is not None:
            rrd_path = str(rrd_writer(out / f"{stem}.rrd", session, durable, document))
            written.append(Path(rrd_path))
            timings["rrd"] = time.perf_counter() - t1
            t1 = time.perf_counter()
        if diagnosis and session.diagnosis is not None:
            diagnosis_path = str(
                write_diagnosis(out / f"{stem}.diagnosis.json", session.diagnosis, durable=durable)
            )
            written.append(Path(diagnosis_path))
        json_path = write_calibration(
            out / f"{stem}.calibration.json", session, None, durable, document
        )
    except BaseException:
        for path in written:
            with contextlib.suppress(OSError):
                path.unlink()
        raise
    timings["write"] = time.perf_counter() - t1
    return WrittenFiles(
        calibration_path=str(json_path),
        diagnosis_path=diagnosis_path,
        rrd_path=rrd_path,
        timings_s=timings,
    )


def keep_as_stale(out: Path, stem: str) -> str | None:
    """Rename a failed session's earlier outputs to ``.stale``; their new names, or None.

    Never deletes: a good earlier result stays on disk, marked so nobody takes it
    for this run's.
    """
    kept = []
    for suffix in OUTPUT_SUFFIXES:
        old = out / f"{stem}{suffix}"
        if not old.exists():
            continue
        kind, _, ext = suffix.rpartition(".")
        new = out / f"{stem}{kind}.stale.{ext}"
        try:
            os.replace(old, new)
        except OSError:
            continue
        kept.append(new.name)
    return ", ".join(kept) or None


def session_outputs(
    path: str, out_dir: str | Path, rrd: bool, diagnose: bool, stem: str | None = None
) -> list:
    """The files one session writes, for the overwrite policy (:mod:`wheelcal.io.ownership`)."""
    from wheelcal.io import Output, origin_of

    stem = stem or session_stem(path)
    origin = origin_of([path])
    names = [f"{stem}.calibration.json"]
    names += [f"{stem}.rrd"] if rrd else []
    names += [f"{stem}.diagnosis.json"] if diagnose else []
    return [Output(Path(out_dir) / name, origin, (str(path),)) for name in names]
