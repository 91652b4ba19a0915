"""One session of a batch: :func:`~wheelcal.calibration.calibrate_into` with the batch's view.

Computing and writing a session are the calibration layer's
(:func:`wheelcal.calibration.calibrate_into`, the same for ``wheelcal calibrate``
and ``diagnose``); the batch adds the ``.rrd``'s writer (:mod:`wheelcal.viz`, a
layer above the calibration) and refuses a device, FIFO or folder before it
hashes an input (:func:`check_regular_file`).
"""

from __future__ import annotations

from pathlib import Path

from wheelcal.calibration import SessionOutcome, calibrate_into
from wheelcal.io import special_file_kind
from wheelcal.recording import RecordingError
from wheelcal.session import SessionOptions


def calibrate_session(
    path: str | Path,
    options: SessionOptions,
    out_dir: str | Path,
    provenance: dict | None = None,
    durable: bool = True,
    stem: str | None = None,
) -> SessionOutcome:
    """Calibrate one recording into ``out_dir`` (:func:`~wheelcal.calibration.calibrate_into`).

    Never raises for bad input; with ``options.rrd`` the view is drawn by
    :func:`wheelcal.viz.write_session_rrd`.
    """
    rrd_writer = None
    if options.rrd:
        from wheelcal.viz import write_session_rrd as rrd_writer
    return calibrate_into(
        path, options, out_dir, provenance, durable=durable, stem=stem, rrd_writer=rrd_writer
    )


def check_regular_file(path: str | Path) -> None:
    """Refuse a device, FIFO or folder before reading it (``/dev/zero`` never ends).

    A missing file is left to the reader, which names it.
    """
    kind = special_file_kind(path)
    if kind is not None:
        raise RecordingError(f"{path}: is {kind}, not a recording file; give an .mcap file")
