"""A session's files: the computed calibration (:mod:`wheelcal.session.compute`) written out.

Used by ``wheelcal calibrate``, ``diagnose`` and the batch runner, so all
behave the same.  Computing (the session layer) and writing (here) are separate:

* :func:`~wheelcal.session.compute.compute_session` reads the recording and runs
  the window, the fit, the closed loop and the gates — no files;
* :func:`write_session` writes the ``.rrd``, the diagnosis and, last, the
  calibration JSON (it marks a complete session for the batch's up-to-date
  check);
* :func:`calibrate_session` does both and never raises for bad input: the
  outcome carries the error (naming the file), the refusing gate and its fix.
  A failed session leaves no calibration: one from an earlier successful run
  of the same file is renamed ``<stem>.calibration.stale.json`` (likewise
  its ``.diagnosis.json`` and ``.rrd``), and the error says so.
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from numpy.linalg import LinAlgError

from wheelcal.io import special_file_kind
from wheelcal.recording import (
    CalibrationRefused,
    RecordingError,
)
from wheelcal.session import SessionOptions, SessionResult, compute_session

#: Outputs of a session, renamed ``<stem>.<kind>.stale.<ext>`` when a re-run fails.
_OUTPUT_SUFFIXES = (".calibration.json", ".diagnosis.json", ".rrd")


@dataclass(frozen=True, eq=False)
class SessionOutcome:
    """The batch's record of one session: what happened, its files, how long it took.

    ``session`` is the calibrated session (the computation's result) or None after
    a failure, whose ``error`` names the file and the problem (``gate`` and ``fix``
    for a refusal).
    """

    source: str
    stem: str
    error: str | None = None
    session: SessionResult | None = None
    calibration_path: str | None = None
    rrd_path: str | None = None
    diagnosis_path: str | None = None
    timings_s: dict[str, float] = field(default_factory=dict)
    #: For a refused calibration: the gate that refused it and the likely fix.
    gate: str | None = None
    fix: str | None = None
    #: Its files could not be written because the disk is full (the batch stops).
    disk_full: bool = False

    @property
    def ok(self) -> bool:
        """True when the session was calibrated (and, after writing, written)."""
        return self.error is None

    @property
    def result(self):
        """The final fit (None after a failure)."""
        return None if self.session is None else self.session.result


def outcome_of(session: SessionResult, stem: str | None = None) -> SessionOutcome:
    """The batch's record of a computed session (before its files are written)."""
    return SessionOutcome(
        source=session.source,
        stem=stem or session_stem(session.source),
        session=session,
        timings_s=dict(session.timings_s),
    )


def session_stem(path: str | Path) -> str:
    """Output stem of a recording: its file name without ``.mcap``."""
    name = Path(path).name
    return name[: -len(".mcap")] if name.endswith(".mcap") else Path(path).stem


def _write_rrd(
    path: Path, session: SessionResult, durable: bool = True, document: dict | None = None
) -> Path:
    """Session .rrd; with a diagnosis that added effects, its before/after tab."""
    from wheelcal.viz import write_session_rrd

    return write_session_rrd(path, session, durable, document)


def write_session(
    outcome: SessionOutcome,
    options: SessionOptions,
    out_dir: str | Path,
    provenance: dict | None = None,
    durable: bool = True,
) -> SessionOutcome:
    """Write a computed session's files; returns the outcome with their paths."""
    from wheelcal.calibration import calibration_dict, write_calibration

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    timings = dict(outcome.timings_s)
    t1 = time.perf_counter()
    stem = outcome.stem
    # The .rrd first: the calibration JSON marks a complete session (the batch's
    # up-to-date check), so it is written last.  If a later file fails (a full
    # disk), the ones this attempt wrote go too: none may pass for a stale
    # earlier result, nor for this run's.
    rrd_path = diagnosis_path = None
    document = calibration_dict(outcome.session, provenance)  # the JSON and the view's verdict
    written: list[Path] = []
    try:
        if options.rrd:
            rrd_path = str(_write_rrd(out / f"{stem}.rrd", outcome.session, durable, document))
            written.append(Path(rrd_path))
            timings["rrd"] = time.perf_counter() - t1
            t1 = time.perf_counter()
        diagnosis = outcome.session.diagnosis
        if options.diagnose and diagnosis is not None:
            from wheelcal.calibration import write_diagnosis

            diagnosis_path = str(
                write_diagnosis(out / f"{stem}.diagnosis.json", diagnosis, durable=durable)
            )
            written.append(Path(diagnosis_path))
        json_path = write_calibration(
            out / f"{stem}.calibration.json", outcome.session, provenance, durable, document
        )
    except BaseException:
        for path in written:
            with contextlib.suppress(OSError):
                path.unlink()
        raise
    timings["write"] = time.perf_counter() - t1
    return replace(
        outcome,
        calibration_path=str(json_path),
        diagnosis_path=diagnosis_path,
        rrd_path=rrd_path,
        timings_s=timings,
    )


def calibrate_session(
    path: str | Path,
    options: SessionOptions,
    out_dir: str | Path,
    provenance: dict | None = None,
    durable: bool = True,
    stem: str | None = None,
) -> SessionOutcome:
    """Calibrate one recording and write ``<out>/<stem>.calibration.json``.

    Never raises for bad input: the outcome carries the error instead, and no
    calibration of this file is left in ``out_dir`` (an earlier one is renamed
    ``.stale``).  ``provenance`` is stored in the JSON (the batch runner's
    up-to-date check).  ``durable=False`` skips the per-file fsyncs (the batch
    syncs once at the end); the files are still written atomically.  ``stem``
    names the outputs (default :func:`session_stem`; a batch passes unique ones).
    """
    source = str(path)
    stem = stem or session_stem(path)
    try:
        outcome = outcome_of(compute_session(path, options), stem)  # the reader refuses FIFOs
    except Exception as exc:
        return _failed_compute(source, stem, out_dir, exc)
    try:
        return write_session(outcome, options, out_dir, provenance, durable)
    except Exception as exc:  # a file that cannot be written: the disk may be full
        from wheelcal.batch.termination import disk_full

        full = disk_full(exc, out_dir)
        message = describe_error(exc) or f"{type(exc).__name__}: {exc}"
        if full:
            message = f"its outputs cannot be written, the disk is full: {message}"
        return failed_outcome(source, stem, out_dir, message, exc, disk_full=full)


def _failed_compute(source: str, stem: str, out_dir, exc: Exception) -> SessionOutcome:
    """The outcome of a session whose computation raised ``exc``: named, never raised."""
    if isinstance(exc, RecordingError | ValueError | ArithmeticError | OSError | LinAlgError):
        return failed_outcome(source, stem, out_dir, describe_error(exc), exc)
    if isinstance(exc, MemoryError | RecursionError):
        # A recording that exhausts memory or the stack fails alone: the next one still runs.
        what = "out of memory" if isinstance(exc, MemoryError) else "input nested too deeply"
        return failed_outcome(source, stem, out_dir, f"{what} ({type(exc).__name__})", exc)
    # one session must never stop the others
    return failed_outcome(
        source, stem, out_dir, f"unexpected error: {type(exc).__name__}: {exc}", exc
    )


def describe_error(exc: BaseException) -> str:
    """An error in words: ``path: Permission denied`` rather than ``[Errno 13] …: 'path'``."""
    if isinstance(exc, OSError) and exc.strerror:
        if exc.filename is None:
            return exc.strerror
        where = f"{exc.filename} -> {exc.filename2}" if exc.filename2 else f"{exc.filename}"
        return f"{where}: {exc.strerror}"
    return str(exc)


def check_regular_file(path: str | Path) -> None:
    """Refuse a device, FIFO or folder before reading it (``/dev/zero`` never ends).

    A missing file is left to the reader, which names it.
    """
    kind = special_file_kind(path)
    if kind is not None:
        raise RecordingError(f"{path}: is {kind}, not a recording file; give an .mcap file")


def failed_outcome(
    source: str,
    stem: str,
    out_dir: str | Path,
    message: str,
    exc: BaseException | None = None,
    disk_full: bool = False,
) -> SessionOutcome:
    """The outcome of a failed session: the error names the file; earlier outputs go stale."""
    if source not in message:
        message = f"{source}: {message}"
    stale = keep_as_stale(Path(out_dir), stem)
    if stale:
        message += f" (the earlier outputs of this file were kept as {stale})"
    refused = exc if isinstance(exc, CalibrationRefused) else None
    return SessionOutcome(
        source=source,
        stem=stem,
        error=message,
        gate=refused.gate if refused else None,
        fix=refused.fix if refused else None,
        disk_full=disk_full,
    )


def keep_as_stale(out: Path, stem: str) -> str | None:
    """Rename a failed session's earlier outputs to ``.stale``; their new names, or None.

    Never deletes: a good earlier result stays on disk, marked so nobody takes it
    for this run's.
    """
    kept = []
    for suffix in _OUTPUT_SUFFIXES:
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
