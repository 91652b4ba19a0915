"""One recording end to end, no files: read → window → fit → closed loop → gates.

:class:`SessionOptions` holds what a user can ask (the command line's values,
checked here so a bad one is a usage error before any file is read);
:func:`compute_session` reads a file and :func:`compute_recording` calibrates a
recording already read.  Both return a frozen :class:`SessionResult`: the
assessed calibration (the closed loop's final model unless ``model="paper"``),
its window and how it was chosen, the loop's report, the recording and the timings.
``wheelcal calibrate``, ``diagnose``, the batch and ``wheelcal.calibrate()`` all
compute a session here, so all give the same numbers.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from wheelcal.estimate.joint import JointFit
from wheelcal.recording import SESSION_FACT_KEYS, Recording
from wheelcal.session.fit import SessionFit
from wheelcal.session.gates import Gates
from wheelcal.session.result import SessionResult

if TYPE_CHECKING:
    from wheelcal.estimate.field import FieldFit

#: Local gravity on Earth lies in this range; outside it needs ``force_gravity``.
EARTH_GRAVITY_RANGE_MPS2 = (9.7, 9.9)
#: What a calibration fits: the closed loop's final model, or the paper's bare model.
MODELS = ("closed_loop", "paper")
#: ``--geometry``: "auto" (read from the data, :mod:`wheelcal.session.auto`), a JointFit mode,
#: or "rolling" (a wheel rolling on the ground: the field fit, :mod:`wheelcal.session.field`).
SESSION_GEOMETRIES = ("auto", "radius", "tilt", "vertical", "rolling")


@dataclass(frozen=True)
class SessionOptions:
    """How to calibrate a session (command-line values; ``None`` = from the file).

    Values are checked here, so a bad option is a usage error before any file
    is read; values read from a recording's metadata are checked by
    :class:`~wheelcal.recording.SessionInfo` and fail that session only.
    """

    topic: str | None = None
    radius_m: float | None = None
    radius_std_m: float | None = None
    gravity_mps2: float | None = None
    full_scale_g: float | None = None
    gyro_full_scale_dps: float | None = None
    sensor_id: str | None = None
    mounting_id: str | None = None
    start_s: float | None = None
    end_s: float | None = None
    geometry: str = "auto"
    known_tilt_deg: float | None = None
    tilt_std_deg: float = 0.5
    rrd: bool = False
    #: ``"closed_loop"`` (default): the paper's model, then every effect it lacks that the
    #: recording shows (README "The closed loop"); ``"paper"``: the paper's model as fitted.
    model: str = "closed_loop"
    #: Write the closed loop's report (``<stem>.diagnosis.json``) too.
    diagnose: bool = False
    #: Family-wise significance level of the closed loop's effect screen.
    alpha: float = 0.01
    accel_unit: str | None = None  # "m/s^2" or "g" when the file misstates its unit
    #: Pipeline defaults: (key, value) pairs used where neither the file nor the
    #: command line gives a value (CONTRACT precedence: CLI > file > pipeline).
    defaults: tuple[tuple[str, object], ...] = ()
    #: Plausibility gates (refusal and warning bands).
    gates: Gates = field(default_factory=Gates)
    #: Accept a gravity outside 9.7–9.9 m/s² (a centrifuge, another planet, a test).
    force_gravity: bool = False
    #: Use of the gyroscope: "auto" (when only it can follow the motion), "on", "off".
    gyro: str = "auto"
    #: σ of the prior on the gyro's sensitivity to linear acceleration, °/s/g (its class).
    gyro_g_sensitivity_dps_per_g: float = 0.1

    def __post_init__(self) -> None:
        if (self.start_s is None) != (self.end_s is None):
            raise ValueError("give both --start-s and --end-s, or neither")
        if self.start_s is not None and not self.end_s > self.start_s:
            raise ValueError(f"--end-s ({self.end_s}) must be after --start-s ({self.start_s})")
        if self.start_s is not None and self.start_s < 0:
            raise ValueError(
                f"--start-s must be >= 0 (s from the first sample), got {self.start_s}"
            )
        _positive("radius", self.radius_m, "m")
        _positive("full scale", self.full_scale_g, "g")
        _positive("--gyro-g-sensitivity", self.gyro_g_sensitivity_dps_per_g, "°/s/g")
        if self.radius_std_m is not None and not (
            np.isfinite(self.radius_std_m) and self.radius_std_m >= 0
        ):
            raise ValueError(f"--radius-std must be >= 0 m, got {self.radius_std_m}")
        if self.gravity_mps2 is not None:
            _positive("gravity", self.gravity_mps2, "m/s²")
            lo, hi = EARTH_GRAVITY_RANGE_MPS2
            if not (lo <= self.gravity_mps2 <= hi or self.force_gravity):
                raise ValueError(
                    f"--gravity {self.gravity_mps2:g} m/s² is not g on Earth ({lo}–{hi}); "
                    "use --force-gravity if you mean it"
                )
        if self.known_tilt_deg is not None and not 0.0 <= self.known_tilt_deg <= 90.0:
            raise ValueError(f"--tilt-deg must lie in [0, 90]°, got {self.known_tilt_deg}")
        if not (np.isfinite(self.tilt_std_deg) and self.tilt_std_deg >= 0):
            raise ValueError(f"--tilt-std-deg must be >= 0, got {self.tilt_std_deg}")
        if not 0 < self.alpha < 1:
            raise ValueError(f"--alpha must lie in (0, 1), got {self.alpha}")
        if self.model not in MODELS:
            raise ValueError(f"--model must be one of {', '.join(MODELS)}, got {self.model!r}")
        if self.diagnose and self.model != "closed_loop":
            raise ValueError("diagnose runs the closed loop: it cannot use --model paper")
        if self.accel_unit not in (None, "m/s^2", "g"):
            raise ValueError(f"--accel-unit must be 'm/s^2' or 'g', got {self.accel_unit!r}")
        if self.geometry not in SESSION_GEOMETRIES:
            raise ValueError(
                f"--geometry must be one of {', '.join(SESSION_GEOMETRIES)}, got {self.geometry!r}"
            )
        if self.geometry == "tilt" and self.known_tilt_deg is None:
            raise ValueError("--geometry tilt needs --tilt-deg")
        if self.gyro not in ("auto", "on", "off"):
            raise ValueError(f"--gyro must be auto, on or off, got {self.gyro!r}")
        unknown = {k for k, _ in self.defaults} - set(SESSION_FACT_KEYS)
        if unknown:
            raise ValueError(f"unknown session fact(s) {sorted(unknown)} in the defaults")

    def info_overrides(self) -> dict[str, object]:
        """Session facts given on the command line (they override the file)."""
        return {k: getattr(self, k) for k in SESSION_FACT_KEYS if getattr(self, k) is not None}

    def info_defaults(self) -> dict[str, object]:
        """Pipeline defaults (used only where the file and the command line are silent)."""
        return dict(self.defaults)

    def fitter(self) -> JointFit:
        """The joint-fit configuration for these options (a fixed axle's).

        ``"auto"`` starts from the paper's geometry (r given, α fitted), and so does
        ``"rolling"``, whose wheel is the field fit's (:meth:`field_fitter`).
        """
        return JointFit(
            geometry=self.geometry if self.geometry in ("tilt", "vertical") else "radius",
            known_tilt_deg=self.known_tilt_deg,
            tilt_std_deg=self.tilt_std_deg,
            gyro_g_prior_dps_per_g=self.gyro_g_sensitivity_dps_per_g,
        )

    def field_fitter(self) -> FieldFit:
        """The field fit's configuration for these options (a wheel in the field)."""
        from wheelcal.estimate.field import FieldFit

        return FieldFit(gyro_g_prior_dps_per_g=self.gyro_g_sensitivity_dps_per_g)

    def session_fit(self) -> SessionFit:
        """Window, joint fit, closed loop (unless ``model="paper"``) and gates."""
        loop = None
        if self.model == "closed_loop":
            from wheelcal.closedloop import ClosedLoop

            loop = ClosedLoop(fit=self.fitter(), alpha=self.alpha)
        return SessionFit(
            fitter=self.fitter(),
            gates=self.gates,
            start_s=self.start_s,
            end_s=self.end_s,
            gyro=self.gyro,
            closed_loop=loop,
            geometry=self.geometry,
        )


def _positive(what: str, value: float | None, unit: str) -> None:
    if value is not None and not (np.isfinite(value) and value > 0):
        raise ValueError(f"{what} must be a positive number of {unit}, got {value}")


def compute_session(path: str | Path, options: SessionOptions) -> SessionResult:
    """Read and calibrate one recording; no files are written.

    Raises :class:`~wheelcal.recording.RecordingError` (including
    :class:`~wheelcal.recording.CalibrationRefused`) and the reader's
    ``InputError`` for bad input.
    """
    from wheelcal.io import read_recording

    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    recording = read_recording(
        path,
        topic=options.topic,
        info_overrides=options.info_overrides(),
        info_defaults=options.info_defaults(),
        accel_unit=options.accel_unit,
        gravity_checked=not options.force_gravity,
    )
    timings["read"] = time.perf_counter() - t0
    return compute_recording(recording, options, timings)


def compute_recording(
    recording: Recording, options: SessionOptions, timings: dict[str, float] | None = None
) -> SessionResult:
    """Calibrate a recording already read and checked (see :func:`compute_session`)."""
    timings = dict(timings or {})
    t1 = time.perf_counter()
    if options.geometry == "auto":
        from wheelcal.session.auto import calibrate_auto

        session = calibrate_auto(recording, options)
    elif options.geometry == "rolling":  # asked for: the field fit, the rolling model
        from wheelcal.session.auto import calibrate_rolling

        session = calibrate_rolling(recording, options)
    else:
        session = options.session_fit().run(recording)
    timings["fit"] = time.perf_counter() - t1
    return dataclasses.replace(session, timings_s=timings)
