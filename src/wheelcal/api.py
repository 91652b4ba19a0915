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

import numpy as np

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


def _checked(recording: Recording, options) -> Recording:
    """An in-memory recording through the reader's sample checks and the session facts."""
    from wheelcal.model.parameters import STANDARD_GRAVITY_MPS2
    from wheelcal.recording.gyro import align_to_samples, check_gyro
    from wheelcal.recording.samples import InputPolicy, clean_samples

    info = recording.info.merged(**options.info_overrides())
    accel = recording.accel_mps2
    if options.accel_unit == "g":
        accel = accel * STANDARD_GRAVITY_MPS2
    time_ns = recording.epoch_unix_ns + np.rint(recording.time_s * 1e9).astype(np.int64)
    clean = clean_samples(
        recording.source,
        time_ns,
        accel,
        unit="m/s^2",
        full_scale_g=info.full_scale_g,
        policy=InputPolicy(),
    )
    notes = recording.notes + clean.notes
    gyro = None
    if recording.gyro_radps is not None:  # the same rows, through the same repairs
        aligned = align_to_samples(time_ns, accel, recording.gyro_radps, clean.time_ns)
        gyro, gyro_notes = check_gyro(recording.source, aligned, info.gyro_full_scale_dps)
        notes += gyro_notes
    temperature = None
    if recording.temperature_c is not None:
        temperature = np.interp(clean.time_ns, time_ns, recording.temperature_c)
    epoch = int(clean.time_ns[0])
    return dataclasses.replace(
        recording,
        time_s=(clean.time_ns - epoch) * 1e-9,
        accel_mps2=clean.accel_mps2,
        epoch_unix_ns=epoch,
        info=info,
        notes=notes,
        clip_limits_mps2=clean.clip_limits_mps2,
        gyro_radps=gyro,
        temperature_c=temperature,
    )


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
        outcome = compute_recording(_checked(source, opts), opts)
    else:
        outcome = compute_session(source, opts)
    return Calibration.from_result(
        outcome.result,
        geometry=opts.geometry,
        window_reason=outcome.window.reason,
        diagnosis=outcome.diagnosis,
        model=opts.model,
    )


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
