"""One recording calibrated into a folder, never raising for bad input: a :class:`SessionOutcome`.

The same value is the batch's record of a session (``wheelcal batch``): without the
calibrated session when it crosses a process boundary, or ``skipped`` when its
outputs were up to date.

``wheelcal calibrate``, ``diagnose`` and the batch's workers all run a session
through :func:`calibrate_into`: :meth:`Calibration.compute
<wheelcal.calibration.document.Calibration.compute>` (read, window, fit, closed
loop, gates — no files), then :meth:`Calibration.write
<wheelcal.calibration.document.Calibration.write>` (the ``.rrd``, the diagnosis
and, last, the calibration JSON).  A failure is an answer, not an exception:
the outcome carries the error (naming the file), the refusing gate and its fix
(:func:`failed_outcome`).  A failed session leaves no calibration: one from an
earlier successful run of the same file is renamed
``<stem>.calibration.stale.json`` (likewise its ``.diagnosis.json`` and
``.rrd``), and the error says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from numpy.linalg import LinAlgError

from wheelcal.calibration.document import Calibration
from wheelcal.calibration.session_files import RrdWriter, keep_as_stale, session_stem
from wheelcal.io import describe_error, disk_full
from wheelcal.recording import CalibrationRefused, RecordingError
from wheelcal.session import SessionOptions, SessionResult


@dataclass(frozen=True, eq=False)
class SessionOutcome:
    """What happened to one session: its calibration or its error, its files, its timings.

    ``session`` is the calibrated session (the computation's result) or None after
    a failure, whose ``error`` names the file and the problem (``gate`` and ``fix``
    for a refusal).  The batch keeps the outcome without its ``session`` (small: it
    crosses process boundaries); ``skipped`` marks a session whose outputs were up
    to date and were not computed again.
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
    #: What the reader repaired and the fit's warnings (⚠), for the batch's progress line.
    notes: tuple[str, ...] = ()
    #: Its outputs were up to date: not computed again (the batch).
    skipped: bool = False

    @property
    def ok(self) -> bool:
        """True when the session was calibrated (and written), or was up to date."""
        return self.error is None

    @property
    def status(self) -> str:
        """``calibrated``, ``up to date`` or ``failed`` (as ``report.json`` ``per_session``)."""
        if not self.ok:
            return "failed"
        return "up to date" if self.skipped else "calibrated"

    @property
    def result(self):
        """The final fit (None after a failure)."""
        return None if self.session is None else self.session.result


def calibrate_into(
    path: str | Path,
    options: SessionOptions,
    folder: str | Path,
    provenance: dict | None = None,
    durable: bool = True,
    stem: str | None = None,
    rrd_writer: RrdWriter | None = None,
) -> SessionOutcome:
    """Calibrate one recording and write ``<folder>/<stem>.calibration.json`` (and the rest).

    Never raises for bad input: the outcome carries the error instead, and no
    calibration of this file is left in ``folder`` (an earlier one is renamed
    ``.stale``).  ``provenance`` is stored in the JSON (the batch runner's
    up-to-date check).  ``durable=False`` skips the per-file fsyncs (the batch
    syncs once at the end); the files are still written atomically.  ``stem``
    names the outputs (default :func:`~wheelcal.calibration.session_files.session_stem`;
    a batch passes unique ones).  ``rrd_writer`` draws the ``.rrd`` that
    ``options.rrd`` asks for (``wheelcal.viz.write_session_rrd``: the view is a
    layer above).
    """
    if options.rrd and rrd_writer is None:
        raise ValueError("options.rrd asks for the .rrd: pass its writer (rrd_writer=)")
    source = str(path)
    stem = stem or session_stem(path)
    try:
        calibration = Calibration.compute(path, options, provenance)  # the reader refuses FIFOs
    except Exception as exc:
        return _failed_compute(source, stem, folder, exc)
    session = calibration.session
    try:
        files = calibration.write(
            folder,
            stem=stem,
            rrd_writer=rrd_writer if options.rrd else None,
            diagnosis=options.diagnose,
            durable=durable,
        )
    except Exception as exc:  # a file that cannot be written: the disk may be full
        full = disk_full(exc, folder)
        message = describe_error(exc) or f"{type(exc).__name__}: {exc}"
        if full:
            message = f"its outputs cannot be written, the disk is full: {message}"
        return failed_outcome(source, stem, folder, message, exc, disk_full=full)
    return SessionOutcome(
        source=session.source,
        stem=stem,
        session=session,
        calibration_path=files.calibration_path,
        rrd_path=files.rrd_path,
        diagnosis_path=files.diagnosis_path,
        timings_s={**session.timings_s, **files.timings_s},
        notes=(*session.result.notes, *(f"⚠ {w}" for w in session.warnings)),
    )


def _failed_compute(source: str, stem: str, folder, exc: Exception) -> SessionOutcome:
    """The outcome of a session whose computation raised ``exc``: named, never raised."""
    if isinstance(exc, RecordingError | ValueError | ArithmeticError | OSError | LinAlgError):
        return failed_outcome(source, stem, folder, describe_error(exc), exc)
    if isinstance(exc, MemoryError | RecursionError):
        # A recording that exhausts memory or the stack fails alone: the next one still runs.
        what = "out of memory" if isinstance(exc, MemoryError) else "input nested too deeply"
        return failed_outcome(source, stem, folder, f"{what} ({type(exc).__name__})", exc)
    # one session must never stop the others
    return failed_outcome(
        source, stem, folder, f"unexpected error: {type(exc).__name__}: {exc}", exc
    )


def failed_outcome(
    source: str,
    stem: str,
    folder: str | Path,
    message: str,
    exc: BaseException | None = None,
    disk_full: bool = False,
) -> SessionOutcome:
    """The outcome of a failed session: the error names the file; earlier outputs go stale."""
    if source not in message:
        message = f"{source}: {message}"
    stale = keep_as_stale(Path(folder), stem)
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
