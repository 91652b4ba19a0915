"""``--geometry auto`` (the default): which wheel this is, decided from the evidence.

:func:`decide_geometry` weighs the evidence and returns a :class:`GeometryDecision`
— the model, why, and the fit it was read from when one was needed.  Without a
gyroscope the recording is a bench's free spin (the paper's geometry: the tilt
fitted, the radius given).  With one:

* **the carrier turns** (the gyro across its axle shows a yaw): a wheel rolling
  in the field — :func:`wheelcal.session.field.calibrate_field`, which fits the
  hub's travel and turns, the camber and the sensor's radius;
* **else, with a radius**: the bench's free spin as without a gyro; if its answer
  is a refusal because the wheel is driven (``motion``, ``undetermined``,
  ``turns``, ``misfit``), the field fit, which tells a rolling wheel (its hub
  travels) from a fixed axle;
* **else** (no radius): the field fit; when it finds no rolling wheel (its hub does
  not travel, or it refuses one), a fixed axle: a vertical one (a stand) is the
  bench's free spin with the radius fitted (geometry ``vertical``); a tilted one
  needs the radius, and is refused by name.

A fit that served as evidence is the answer when the decision keeps it (nothing
is fitted twice), and a refusal is an answer like a calibration: fits are
*attempted* (:meth:`~wheelcal.session.fit.SessionFit.attempt`,
:func:`~wheelcal.session.field.field_attempt`) and their answers weighed as values.
``--geometry rolling`` gives the geometry instead of deciding it: the field fit
(:func:`calibrate_rolling`), the one model of a wheel rolling on the ground.

The session says which geometry it was and why (``SessionResult.geometry_source`` =
``"detected"``, ``geometry_reason``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from wheelcal.estimate.field import YAW_RMS_RADPS, gyro_axle
from wheelcal.recording import CalibrationRefused, Recording, RecordingError
from wheelcal.session.field import field_attempt, is_vertical_axle, yaw_rms_radps
from wheelcal.session.result import SessionResult, WindowChoice

#: Refusals of the bench's free spin that a wheel in the field explains.
FIELD_CAN_HELP = ("motion", "undetermined", "turns", "misfit")
#: The models :func:`decide_geometry` chooses from (``"refused"``: none fits).
MODELS = ("bench", "field", "vertical", "refused")


@dataclass(frozen=True, eq=False)
class GeometryDecision:
    """The model that calibrates a recording (``--geometry auto``), and why.

    ``model`` is one of :data:`MODELS`: ``"bench"`` (the free spin, the radius given,
    the tilt fitted), ``"field"`` (a wheel in the field), ``"vertical"`` (a vertical
    fixed axle: the free spin with the radius fitted) or ``"refused"``.  ``answer``
    is the fit the decision was read from, when one was needed as evidence (a
    session, or the refusal that answers the recording); None when the model is
    still to be fitted.
    """

    model: str
    reason: str
    answer: SessionResult | RecordingError | None = None

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}, got {self.model!r}")
        if self.model == "refused" and not isinstance(self.answer, RecordingError):
            raise ValueError("a refused geometry carries its refusal as the answer")


def decide_geometry(recording: Recording, options) -> GeometryDecision:
    """The model for ``recording`` from its evidence (module docstring).

    The evidence is read cheapest first — a gyroscope, the carrier's turning, a
    radius — and a fit is attempted only where those leave the choice open (the
    bench's free spin with a radius; the field fit's hub travel without one).
    ``options`` is the session's :class:`~wheelcal.session.compute.SessionOptions`.
    """
    has_gyro = recording.gyro_radps is not None and options.gyro != "off"
    if not has_gyro:
        return GeometryDecision(
            "bench", "no gyroscope: a bench's free spin (the radius given, the tilt fitted)"
        )
    yaw = yaw_rms_radps(recording)
    if yaw > YAW_RMS_RADPS:
        why = f"the gyroscope shows the wheel's carrier turning ({yaw:.3g} rad/s rms)"
        return GeometryDecision("field", why)
    if recording.info.radius_m is not None:
        bench = dataclasses.replace(options, geometry="radius").session_fit().attempt(recording)
        if isinstance(bench, CalibrationRefused) and bench.gate in FIELD_CAN_HELP:
            why = f"the bench's free spin was refused ({bench.gate}: {bench.reason})"
            return GeometryDecision("field", why)
        return GeometryDecision("bench", "a fixed axle: the carrier does not turn", bench)
    field = field_attempt(
        recording,
        options.gates,
        options.field_fitter(),
        why="no radius given: the geometry from the data",
    )
    if isinstance(field, RecordingError):
        # The field fit could not read a rolling wheel: a wheel on a fixed axle.
        gate = field.gate if isinstance(field, CalibrationRefused) else "error"
        return _fixed_axle(recording, None, f"the field fit refused it as a rolling wheel: {gate}")
    session, fitted = field
    if fitted.geometry.kind == "rolling":
        return GeometryDecision("field", session.geometry_reason, session)
    return _fixed_axle(recording, fitted.axle.axis, fitted.geometry.reason)


def _fixed_axle(recording: Recording, axis, why: str) -> GeometryDecision:
    """No radius, a fixed axle: a vertical wheel fits its radius; a tilted one needs it."""
    if axis is None and recording.gyro_radps is not None:
        axle = gyro_axle(recording.time_s, recording.gyro_radps)
        axis = None if axle is None else axle.axis
    if axis is not None and is_vertical_axle(recording, axis):
        return GeometryDecision(
            "vertical", f"{why}; the axle is horizontal: a vertical wheel on a stand"
        )
    refusal = RecordingError(
        f"{recording.source}: no radius given: the wheel turns on a tilted fixed axle ({why}), "
        "and the radius (the sensor's distance from the axle, measured) is needed to scale "
        "the gains — give --radius"
    )
    return GeometryDecision("refused", why, refusal)


def answer_of(
    decision: GeometryDecision, recording: Recording, options
) -> SessionResult | RecordingError:
    """The decided model's answer: the fit the decision kept, else the model fitted now."""
    if decision.model == "refused":
        return decision.answer
    if decision.model == "field":  # a rolling wheel's field fit, or to fit now
        if decision.answer is not None:
            return decision.answer
        return _judge_field(recording, options, decision.reason)
    answer = decision.answer
    if answer is None:
        geometry = "radius" if decision.model == "bench" else "vertical"
        answer = dataclasses.replace(options, geometry=geometry).session_fit().attempt(recording)
    if isinstance(answer, RecordingError):
        return answer
    return dataclasses.replace(
        answer, geometry=decision.model, geometry_source="detected", geometry_reason=decision.reason
    )


#: The fix a refused field fit of a wheel that should roll suggests.
FREE_SPIN_FIX = "record a free spin on the bench (push once, then let go), or give --geometry"


def _judge_field(
    recording: Recording,
    options,
    why: str,
    window: WindowChoice | None = None,
    fix: str = FREE_SPIN_FIX,
) -> SessionResult | RecordingError:
    """The field fit of a wheel that should roll: its session, else a refusal (``motion``)."""
    field = field_attempt(recording, options.gates, options.field_fitter(), window, why=why)
    if isinstance(field, RecordingError):
        return field
    session, fitted = field
    if fitted.geometry.kind == "rolling":
        return session
    return CalibrationRefused(
        recording.source,
        "motion",
        f"{why}, but the wheel neither rolls nor turns on a fixed axle as a free spin: "
        f"{fitted.geometry.reason}",
        fix,
    )


def calibrate_rolling(recording: Recording, options) -> SessionResult:
    """``--geometry rolling``: the wheel rolls on the ground, so the field fit calibrates it.

    The geometry is given, not decided: no bench fit is tried.  The field fit
    (:func:`~wheelcal.session.field.calibrate_field`) takes the radius when one is
    given and fits it otherwise; a wheel it finds neither rolling nor turning is
    refused (``motion``), as the decision's field fit is.  Raises the refusal.
    """
    if recording.gyro_radps is None or options.gyro == "off":
        raise RecordingError(
            f"{recording.source}: the rolling geometry needs the recording's gyroscope "
            "(the wheel's angle and the carrier's turns are read from it)"
        )
    window = None
    if options.start_s is not None:
        reason = f"window given on the command line: {options.start_s:g}–{options.end_s:g} s"
        window = WindowChoice(recording.window(options.start_s, options.end_s), None, reason)
    why = "the rolling geometry was given (a wheel rolling on the ground)"
    fix = "for a wheel on a fixed axle, give --geometry auto (the default) or radius"
    answer = _judge_field(recording, options, why, window, fix)
    if isinstance(answer, RecordingError):
        raise answer
    return dataclasses.replace(answer, geometry_source="given")


def calibrate_auto(recording: Recording, options) -> SessionResult:
    """Calibrate ``recording`` with the geometry decided from it (module docstring).

    ``options`` is the session's :class:`~wheelcal.session.compute.SessionOptions`
    (its ``geometry`` is ``"auto"``).  Raises the refusal when that is the answer.
    """
    answer = answer_of(decide_geometry(recording, options), recording, options)
    if isinstance(answer, RecordingError):
        raise answer
    return answer
