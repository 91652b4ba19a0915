"""A calibrated session: the fit, what the gates made of it, and where it came from.

Also :func:`attempted`: a fit's answer as a value — its session, or the refusal
(:class:`~wheelcal.recording.RecordingError`, :class:`~wheelcal.recording.CalibrationRefused`
included) it ended in, which the caller weighs like any other answer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypeVar

from wheelcal.closedloop import Diagnosis
from wheelcal.estimate import RestSegment
from wheelcal.estimate.joint import CalibrationResult, FreedCheck
from wheelcal.recording import Recording, RecordingError
from wheelcal.session.gates import Assessment
from wheelcal.session.window import FreeSpinWindow


@dataclass(frozen=True, eq=False)
class WindowChoice:
    """The window a calibration used, and how it was chosen."""

    recording: Recording  # cut to the window
    found: FreeSpinWindow | None
    reason: str


@dataclass(frozen=True)
class CamberTrackReport:
    """Whether the fit followed the camber the gyro tracks, and that track's size (degrees)."""

    followed: bool
    #: The camber's 2–98 % range as the gyro tracks it.
    gyro_range_deg: float
    #: The part of that range the gyro's own errors do not explain.
    beyond_gyro_errors_deg: float
    reason: str


@dataclass(frozen=True)
class LeanReport:
    """A rolling wheel's camber as the gyro reads it over the drive (``bench.lean``).

    ``change_deg`` is the 2–98 % range, the ``lean`` gate's measure.  When measured,
    the part that follows the turns: its slope ``in_turns_deg_per_mps2`` per m/s² of
    lateral acceleration with its σ, and its range ``in_turns_deg`` (all three or
    none).  ``track``: the camber the gyro tracks and whether the fit followed it;
    ``check``: what a camber free to move would change.
    """

    change_deg: float
    in_turns_deg_per_mps2: float | None = None
    in_turns_std_deg_per_mps2: float | None = None
    in_turns_deg: float | None = None
    track: CamberTrackReport | None = None
    check: FreedCheck | None = None


@dataclass(frozen=True, eq=False)
class SessionResult:
    """One recording calibrated: the final fit and its assessment, the window, the loop's report.

    ``result`` is the fit the gates judged — the closed loop's final model, or the
    paper's model with ``model="paper"`` — and ``assessment`` what the gates made of
    it (noise floor, motion and rest checks, undetermined parameters, warnings, the
    gyroscope's calibration).  ``diagnosis`` is the closed loop's report (None for
    the paper's model), ``rests`` the rests it was judged by, ``recording`` the whole
    recording, ``geometry`` and ``model`` what was fitted (``model="field"``: a wheel in
    the field, :mod:`wheelcal.session.field`), ``geometry_source`` whether the geometry
    was given or read from the data, and ``geometry_reason`` why.
    """

    source: str
    result: CalibrationResult
    assessment: Assessment
    window: WindowChoice
    rests: tuple[RestSegment, ...]
    diagnosis: Diagnosis | None
    recording: Recording
    geometry: str = "radius"
    model: str = "closed_loop"
    timings_s: dict[str, float] = field(default_factory=dict)
    #: "given" (the options chose the geometry) or "detected" (read from the data).
    geometry_source: str = "given"
    #: Why the geometry is what it is, when detected.
    geometry_reason: str = ""
    #: A rolling wheel's camber as the gyro reads it over the drive (rolling field fits only).
    lean: LeanReport | None = None

    @property
    def undetermined(self) -> tuple[str, ...]:
        """Parameters this recording cannot determine (reported as null)."""
        return self.assessment.undetermined_names

    @property
    def warnings(self) -> tuple[str, ...]:
        """The fit's own warnings, then the gates'."""
        return self.result.warnings + self.assessment.warnings

    @property
    def gyro(self):
        """The gyroscope's calibration, when the recording has one (else None)."""
        return self.assessment.gyro


T = TypeVar("T")


def attempted(fit: Callable[..., T], *args) -> T | RecordingError:
    """``fit(*args)``'s answer, or the refusal it ended in, as a value.

    The gates refuse by raising (the API's and the command line's contract); a
    session that weighs one answer against another (the geometry, the gyro's help)
    turns each fit's ending into a value here, once, and decides on values.
    Other exceptions (a bug, memory) are not answers and pass through.
    """
    try:
        return fit(*args)
    except RecordingError as refusal:
        return refusal
