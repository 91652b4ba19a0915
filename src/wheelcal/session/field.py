"""A recording of a wheel in the field → a calibration: the drive, the field fit, the gates.

The geometry is read from the data (:mod:`wheelcal.estimate.field`): a rolling
wheel — vertical or cambered, the camber measured by its turns — or a fixed
axle.  :func:`calibrate_field` runs it on the drive (first motion to last,
stops and turns kept) and judges the answer like any other calibration
(:func:`wheelcal.session.fit.assess`): parameters the drive cannot determine are
reported null with the reason, a misfit is refused.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from wheelcal.estimate import find_rests
from wheelcal.estimate.field import FieldFit, FieldResult
from wheelcal.recording import Recording, RecordingError
from wheelcal.session.fit import assess
from wheelcal.session.gates import Gates
from wheelcal.session.lean_gate import camber_nulls, judge_the_lean
from wheelcal.session.result import (
    CamberTrackReport,
    LeanReport,
    SessionResult,
    WindowChoice,
    attempted,
)
from wheelcal.session.window import find_drive_window


def field_window(recording: Recording) -> WindowChoice:
    """The drive: from the gyro's first motion to its last, stops included."""
    found = find_drive_window(recording)
    return WindowChoice(recording.window(found.start_s, found.end_s), found, found.reason)


def calibrate_field(
    recording: Recording,
    gates: Gates | None = None,
    fit: FieldFit | None = None,
    window: WindowChoice | None = None,
    why: str = "",
) -> tuple[SessionResult, FieldResult]:
    """Calibrate a wheel in the field (module docstring); also the field fit's own result.

    ``why`` says why the field fit was chosen (it joins the geometry's reason).
    Raises :class:`~wheelcal.recording.RecordingError` without a gyroscope, and
    :class:`~wheelcal.recording.CalibrationRefused` as the gates do.
    """
    gates = gates or Gates()
    if recording.gyro_radps is None:
        raise RecordingError(f"{recording.source}: a wheel in the field needs the gyroscope")
    window = window or field_window(recording)
    drive = window.recording
    field = (fit or FieldFit()).fit(drive)
    nulled = dict(camber_nulls(field, gates))
    nulled.update(judge_the_lean(recording.source, field, gates))
    span = (float(drive.time_s[0]), float(drive.time_s[-1]))
    rests = find_rests(recording, span)
    assessment = assess(field.result, rests, gates, nulled=tuple(nulled.items()))
    turns = _lean_in_turns_warning(field)
    if turns:
        assessment = dataclasses.replace(assessment, warnings=(*assessment.warnings, turns))
    reason = "; ".join(x for x in (why, field.geometry.reason) if x)
    session = SessionResult(
        source=recording.source,
        result=field.result,
        assessment=assessment,
        window=window,
        rests=rests,
        diagnosis=None,
        recording=recording,
        geometry="rolling" if field.geometry.kind == "rolling" else "vertical",
        model="field",
        geometry_source="detected",
        geometry_reason=reason,
        lean=_lean(field) if field.geometry.kind == "rolling" else None,
    )
    return session, field


def field_attempt(
    recording: Recording,
    gates: Gates | None = None,
    fit: FieldFit | None = None,
    window: WindowChoice | None = None,
    why: str = "",
) -> tuple[SessionResult, FieldResult] | RecordingError:
    """:func:`calibrate_field`'s answer as a value: the session and the fit, or the refusal."""
    return attempted(calibrate_field, recording, gates, fit, window, why)


def _lean(field: FieldResult) -> LeanReport:
    """The camber's change over the drive, how it was modelled, and the lean check (degrees)."""
    turns = field.geometry.lean_in_turns
    in_turns = {}
    if turns is not None and np.isfinite(turns.std_rad):
        in_turns = {
            "in_turns_deg_per_mps2": float(np.rad2deg(turns.per_lateral_mps2_rad)),
            "in_turns_std_deg_per_mps2": float(np.rad2deg(turns.std_rad)),
            "in_turns_deg": float(np.rad2deg(turns.range_rad)),
        }
    camber = field.geometry.camber
    track = None
    if camber is not None:
        track = CamberTrackReport(
            followed=bool(camber.used),
            gyro_range_deg=float(np.rad2deg(camber.track_range_rad)),
            beyond_gyro_errors_deg=float(np.rad2deg(camber.unexplained_range_rad)),
            reason=camber.reason,
        )
    return LeanReport(
        change_deg=float(field.geometry.lean_change_deg),
        **in_turns,
        track=track,
        check=field.geometry.lean_check,
    )


#: A lean that follows the turns is named in a warning from this size (2–98 % range, °) …
LEAN_IN_TURNS_WARNING_DEG = 0.2
#: … where its slope k stands this many σ from zero.
LEAN_IN_TURNS_Z = 5.0


def _lean_in_turns_warning(field: FieldResult) -> str:
    """A warning when the camber follows the turns but the model holds it at one value.

    (With the camber following the gyro's track the model has the roll; the figures
    stay in the JSON's ``bench.lean``.)
    """
    turns = field.geometry.lean_in_turns
    if field.geometry.kind != "rolling" or turns is None:
        return ""
    if field.geometry.camber is not None and field.geometry.camber.used:
        return ""
    size = float(np.rad2deg(turns.range_rad))
    if size < LEAN_IN_TURNS_WARNING_DEG or turns.z < LEAN_IN_TURNS_Z:
        return ""
    k, std = np.rad2deg(abs(turns.per_lateral_mps2_rad)), np.rad2deg(turns.std_rad)
    return (
        f"the wheel's camber follows the turns: {k:.3f} ± {std:.3f}°/(m/s²) of lateral "
        f"acceleration, {size:.2f}° over the drive (the carrier rolls in its turns); the model "
        "has one camber, and on simulated cars a lean of half a degree moved the camber and "
        "an offset by several σ — calibrate from straight runs, or read those with care"
    )


def yaw_rms_radps(recording: Recording) -> float:
    """The carrier's yaw seen by the gyro over the drive (rad/s rms; 0 without motion).

    Phase-free (the size of the gyro across its axle, less its noise): no fit needed.
    """
    from wheelcal.estimate.field import gyro_axle

    if recording.gyro_radps is None:
        return 0.0
    try:
        drive = field_window(recording).recording
    except RecordingError:
        return 0.0
    axle = gyro_axle(drive.time_s, drive.gyro_radps)
    return 0.0 if axle is None else float(axle.yaw_rms_radps)


def is_vertical_axle(recording: Recording, axis: np.ndarray) -> bool:
    """Whether the mean specific force along the gyro's axle is near zero (a vertical wheel)."""
    along = float(np.mean(recording.accel_mps2 @ axis))
    return abs(along) < recording.info.gravity_or_standard_mps2 * np.sin(np.deg2rad(5.0))
