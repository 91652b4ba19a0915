"""The Python API: what ``wheelcal calibrate`` and ``wheelcal diagnose`` do, for notebooks.

::

    import wheelcal

    rec = wheelcal.read_recording("spin.mcap")          # a typed Recording
    cal = wheelcal.calibrate(rec, radius_m=0.28)        # or the path itself
    print(cal.summary())
    corrected = cal.apply(rec.accel_mps2)

A refused session raises :class:`wheelcal.CalibrationRefused` (with ``gate``,
``reason`` and ``fix``) — never a silent result.  Options are the command
line's, as keywords (``topic``, ``start_s``/``end_s``, ``geometry``,
``gates=wheelcal.Gates(...)`` …); a misspelt option is a ``TypeError``.
"""

from __future__ import annotations

import dataclasses
import os

from wheelcal.calibration.document import Calibration
from wheelcal.recording import Recording


def read_recording(path: str | os.PathLike, **kwargs) -> Recording:
    """Read and check an MCAP recording (see :func:`wheelcal.io.read_recording`)."""
    from wheelcal.io import read_recording as _read

    return _read(path, **kwargs)


def _options(radius_m, options: dict):
    from wheelcal.session.compute import SessionOptions

    allowed = {f.name for f in dataclasses.fields(SessionOptions)} - {"rrd", "defaults"}
    unknown = sorted(set(options) - allowed)
    if unknown:
        raise TypeError(f"unknown option(s) {unknown}; allowed: {sorted(allowed)}")
    return SessionOptions(radius_m=radius_m, **options)


def calibrate(
    source: str | os.PathLike | Recording, radius_m: float | None = None, **options
) -> Calibration:
    """Calibrate one recording (a path or a :class:`~wheelcal.recording.Recording`).

    Raises
    ------
    CalibrationRefused
        A plausibility gate refused the result (README "When wheelcal refuses").
    wheelcal.io.InputError, RecordingError
        The recording cannot be read or used (the message names it and the problem).
    TypeError
        An unknown option.
    """
    from wheelcal.session.compute import compute_recording, compute_session

    opts = _options(radius_m, options)
    if isinstance(source, Recording):
        info = source.info.merged(**opts.info_overrides())
        outcome = compute_recording(source.checked(unit=opts.accel_unit, info=info), opts)
    else:
        outcome = compute_session(source, opts)
    return Calibration.from_session(outcome)


def diagnose(
    source: str | os.PathLike | Recording,
    radius_m: float | None = None,
    alpha: float = 0.01,
    **options,
) -> Calibration:
    """:func:`calibrate`, named for the closed loop's report it carries.

    Every calibration runs the closed loop (unless ``model="paper"``), so this
    returns the same numbers as :func:`calibrate`; its ``diagnosis`` holds the steps
    (:class:`~wheelcal.closedloop.loop.Diagnosis`).
    """
    return calibrate(source, radius_m=radius_m, diagnose=True, alpha=alpha, **options)
