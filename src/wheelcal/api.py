"""The Python API: what ``wheelcal calibrate`` and ``wheelcal diagnose`` do, for notebooks.

Layer 9 (above ``batch`` and ``study``, beside ``cli``).

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
import re

from wheelcal.calibration import Calibration
from wheelcal.recording import CalibrationRefused, Recording

#: The command line's options as this API's keywords, for a refusal's words
#: (the gates speak the command line's language; ``calibrate`` translates them).
KEYWORDS = {
    "--radius": "radius_m=",
    "--radius-std": "radius_std_m=",
    "--start-s": "start_s=",
    "--end-s": "end_s=",
    "--topic": "topic=",
    "--geometry": "geometry=",
    "--tilt-deg": "known_tilt_deg=",
    "--tilt-std-deg": "tilt_std_deg=",
    "--gravity": "gravity_mps2=",
    "--force-gravity": "force_gravity=True",
    "--full-scale-g": "full_scale_g=",
    "--gyro": "gyro=",
    "--gyro-g-sensitivity": "gyro_g_sensitivity_dps_per_g=",
    "--model": "model=",
    "--alpha": "alpha=",
    "--gain-tolerance": "gates=wheelcal.Gates(gain_tolerance=...)",
    "--offset-tolerance-g": "gates=wheelcal.Gates(offset_tolerance_g=...)",
    "--max-lean-change-deg": "gates=wheelcal.Gates(max_lean_change_deg=...)",
}
_UNIT_OPTION = re.compile(r"--accel-unit (m/s\^2|g)\b")
_OPTION = re.compile(r"--[a-z][a-z0-9-]*")


def api_words(text: str) -> str:
    """A message in this API's words: ``--radius`` → ``radius_m=`` (:data:`KEYWORDS`)."""
    text = _UNIT_OPTION.sub(lambda m: f"accel_unit={m.group(1)!r}", text)
    return _OPTION.sub(lambda m: KEYWORDS.get(m.group(0), m.group(0)), text)


def _in_api_words(refusal: CalibrationRefused) -> CalibrationRefused:
    """The same refusal, its reason and fix naming keywords instead of options."""
    return CalibrationRefused(
        refusal.source, refusal.gate, api_words(refusal.reason), api_words(refusal.fix)
    )


def read_recording(path: str | os.PathLike, **kwargs) -> Recording:
    """Read and check an MCAP recording (see :func:`wheelcal.io.read_recording`)."""
    from wheelcal.io import read_recording as _read

    return _read(path, **kwargs)


def _options(radius_m, options: dict):
    from wheelcal.session import SessionOptions

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
        A plausibility gate refused the result (README "When wheelcal refuses");
        its ``reason`` and ``fix`` name this function's keywords (``radius_m=``),
        not the command line's options.
    wheelcal.io.InputError, RecordingError
        The recording cannot be read or used (the message names it and the problem).
    TypeError
        An unknown option.
    """
    opts = _options(radius_m, options)
    try:
        return Calibration.compute(source, opts)  # the one session function
    except CalibrationRefused as refusal:
        raise _in_api_words(refusal) from None


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
