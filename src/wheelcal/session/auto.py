"""``--geometry auto`` (the default): which wheel this is, read from the data.

Without a gyroscope the recording is a bench's free spin (the paper's
geometry: the tilt fitted, the radius given).  With one:

* **the carrier turns** (the gyro across its axle shows a yaw): a wheel rolling
  in the field — :func:`wheelcal.session.field.calibrate_field`, which fits the
  hub's travel and turns, the camber and the sensor's radius;
* **else, with a radius**: the bench's free spin as without a gyro; if that is
  refused because the wheel is driven (``motion``, ``undetermined``, ``turns``,
  ``misfit``), the field fit, which tells a rolling wheel (its hub travels) from a
  fixed axle;
* **else** (no radius): the field fit; on a fixed axle that is vertical (a stand)
  the bench's free spin with the radius fitted (geometry ``vertical``); a tilted
  fixed axle needs the radius, and is refused by name.

The answer says which it was and why (``SessionResult.geometry_source`` =
``"detected"``, ``geometry_reason``).
"""

from __future__ import annotations

import dataclasses

from wheelcal.estimate.field import YAW_RMS_RADPS, gyro_axle
from wheelcal.recording import CalibrationRefused, Recording, RecordingError
from wheelcal.session.field import calibrate_field, is_vertical_axle, yaw_rms_radps
from wheelcal.session.result import SessionResult

#: Refusals of the bench's free spin that a wheel in the field explains.
FIELD_CAN_HELP = ("motion", "undetermined", "turns", "misfit")


def _detected(session: SessionResult, geometry: str, reason: str) -> SessionResult:
    return dataclasses.replace(
        session, geometry=geometry, geometry_source="detected", geometry_reason=reason
    )


def calibrate_auto(recording: Recording, options) -> SessionResult:
    """Calibrate ``recording`` with the geometry read from it (module docstring).

    ``options`` is the session's :class:`~wheelcal.session.compute.SessionOptions`
    (its ``geometry`` is ``"auto"``).
    """
    bench = dataclasses.replace(options, geometry="radius")
    has_gyro = recording.gyro_radps is not None and options.gyro != "off"
    if not has_gyro:
        why = "no gyroscope: a bench's free spin (the radius given, the tilt fitted)"
        return _detected(bench.session_fit().run(recording), "bench", why)
    yaw = yaw_rms_radps(recording)
    if yaw > YAW_RMS_RADPS:
        why = f"the gyroscope shows the wheel's carrier turning ({yaw:.3g} rad/s rms)"
        return _field(recording, options, why)
    if recording.info.radius_m is not None:
        try:
            session = bench.session_fit().run(recording)
        except CalibrationRefused as exc:
            if exc.gate not in FIELD_CAN_HELP:
                raise
            why = f"the bench's free spin was refused ({exc.gate}: {exc.reason})"
            return _field(recording, options, why)
        return _detected(session, "bench", "a fixed axle: the carrier does not turn")
    try:
        session, field = calibrate_field(
            recording,
            options.gates,
            options.field_fitter(),
            why="no radius given: the geometry from the data",
        )
    except (CalibrationRefused, RecordingError) as exc:
        # The field fit could not read a rolling wheel: a wheel on a fixed axle.
        gate = exc.gate if isinstance(exc, CalibrationRefused) else "error"
        why = f"the field fit refused it as a rolling wheel: {gate}"
        return _fixed_axle(recording, options, None, why)
    if field.geometry.kind == "rolling":
        return session
    return _fixed_axle(recording, options, field.axle.axis, field.geometry.reason)


def _fixed_axle(recording: Recording, options, axis, why: str) -> SessionResult:
    """No radius, a fixed axle: a vertical wheel fits its radius; a tilted one needs it."""
    if axis is None and recording.gyro_radps is not None:
        axle = gyro_axle(recording.time_s, recording.gyro_radps)
        axis = None if axle is None else axle.axis
    if axis is not None and is_vertical_axle(recording, axis):
        stand = dataclasses.replace(options, geometry="vertical")
        why = f"{why}; the axle is horizontal: a vertical wheel on a stand"
        return _detected(stand.session_fit().run(recording), "vertical", why)
    raise RecordingError(
        f"{recording.source}: no radius given: the wheel turns on a tilted fixed axle ({why}), "
        "and the radius (the sensor's distance from the axle, measured) is needed to scale "
        "the gains — give --radius"
    )


def _field(recording: Recording, options, why: str) -> SessionResult:
    session, field = calibrate_field(recording, options.gates, options.field_fitter(), why=why)
    if field.geometry.kind == "rolling":
        return session
    raise CalibrationRefused(
        recording.source,
        "motion",
        f"{why}, but the wheel neither rolls nor turns on a fixed axle as a free spin: "
        f"{field.geometry.reason}",
        "record a free spin on the bench (push once, then let go), or give --geometry",
    )
