"""One session end to end: read → free-spin window → joint fit → calibration JSON (→ .rrd).

Used by ``wheelcal calibrate`` and by the batch runner, so both behave the same.
Bad input never escapes as a traceback: :func:`calibrate_session` returns a
:class:`SessionOutcome` with the error text (naming the file) instead, and
writes nothing for that session.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from wheelcal.estimate.joint import JointFit
from wheelcal.estimate.result import CalibrationResult
from wheelcal.estimate.window import FreeSpinWindow, find_free_spin
from wheelcal.recording import (
    SESSION_FACT_KEYS,
    CalibrationRefused,
    Recording,
    RecordingError,
)

#: The fit needs this many wheel turns in the window (paper: ~100 in 90 s).
MIN_TURNS = 10.0


@dataclass(frozen=True)
class SessionOptions:
    """How to calibrate a session (command-line values; ``None`` = from the file)."""

    topic: str | None = None
    radius_m: float | None = None
    radius_std_m: float | None = None
    gravity_mps2: float | None = None
    full_scale_g: float | None = None
    sensor_id: str | None = None
    mounting_id: str | None = None
    start_s: float | None = None
    end_s: float | None = None
    geometry: str = "radius"
    known_tilt_deg: float | None = None
    tilt_std_deg: float = 0.5
    rrd: bool = False
    #: Run the closed loop (find and fit effects the paper's model lacks).
    diagnose: bool = False
    alpha: float = 0.01
    accel_unit: str | None = None  # "m/s^2" or "g" when the file misstates its unit
    #: Pipeline defaults: (key, value) pairs used where neither the file nor the
    #: command line gives a value (CONTRACT precedence: CLI > file > pipeline).
    defaults: tuple[tuple[str, object], ...] = ()

    def __post_init__(self) -> None:
        if (self.start_s is None) != (self.end_s is None):
            raise ValueError("give both --start-s and --end-s, or neither")
        if self.start_s is not None and not self.end_s > self.start_s:
            raise ValueError(f"--end-s ({self.end_s}) must be after --start-s ({self.start_s})")

    def info_overrides(self) -> dict[str, object]:
        """Session facts given on the command line (they override the file)."""
        return {k: getattr(self, k) for k in SESSION_FACT_KEYS if getattr(self, k) is not None}

    def info_defaults(self) -> dict[str, object]:
        """Pipeline defaults (used only where the file and the command line are silent)."""
        return dict(self.defaults)

    def fitter(self) -> JointFit:
        """The joint-fit configuration for these options."""
        return JointFit(
            geometry=self.geometry,
            known_tilt_deg=self.known_tilt_deg,
            tilt_std_deg=self.tilt_std_deg,
        )


@dataclass(frozen=True, eq=False)
class SessionOutcome:
    """What happened to one session."""

    source: str
    stem: str
    error: str | None = None
    result: CalibrationResult | None = None
    window: FreeSpinWindow | None = None
    window_reason: str = ""
    calibration_path: str | None = None
    rrd_path: str | None = None
    timings_s: dict[str, float] = field(default_factory=dict)
    diagnosis: object | None = None  # wheelcal.diagnose.closed_loop.Diagnosis
    diagnosis_path: str | None = None
    #: For a refused calibration: the gate that refused it and the likely fix.
    gate: str | None = None
    fix: str | None = None

    @property
    def ok(self) -> bool:
        """True when the session was calibrated and written."""
        return self.error is None


def session_stem(path: str | Path) -> str:
    """Output stem of a recording: its file name without ``.mcap``."""
    name = Path(path).name
    return name[: -len(".mcap")] if name.endswith(".mcap") else Path(path).stem


def free_spin(
    recording: Recording, options: SessionOptions
) -> tuple[Recording, FreeSpinWindow | None, str]:
    """Cut the recording to its free-spin window (automatic unless given)."""
    if options.start_s is not None:
        reason = f"window given on the command line: {options.start_s:g}–{options.end_s:g} s"
        return recording.window(options.start_s, options.end_s), None, reason
    found = find_free_spin(recording)
    return recording.window(found.start_s, found.end_s), found, found.reason


def check_turns(result: CalibrationResult) -> float:
    """Turns of the wheel in the fitted window; raises if too few to calibrate."""
    t = result.centred_time_s
    turns = abs(
        float(result.params.spin.theta_at(t[-1:])[0] - result.params.spin.theta_at(t[:1])[0])
    )
    turns /= 2 * np.pi
    if turns < MIN_TURNS:
        raise RecordingError(
            f"{result.source}: the wheel turned only {turns:.1f} times in the fitted window "
            f"(need at least {MIN_TURNS:g}): spin it harder or record longer"
        )
    return turns


def _write_rrd(path: Path, result, recording, window, diagnosis, durable: bool = True) -> Path:
    """Session .rrd; with a diagnosis, the paper's model's residual is a second set."""
    from wheelcal.viz.session_rrd import session_rrd, wheel_angle_rad

    with session_rrd(path, result, recording, window, durable=durable) as rrd:
        if diagnosis is not None and diagnosis.steps:
            base = diagnosis.base
            shift_s = (base.epoch_unix_ns - recording.epoch_unix_ns) * 1e-9
            rrd.log_residuals(
                "paper_model", base.time_s + shift_s, base.residual_mps2, wheel_angle_rad(base)
            )
    return path


def calibrate_session(
    path: str | Path,
    options: SessionOptions,
    out_dir: str | Path,
    provenance: dict | None = None,
    durable: bool = True,
    stem: str | None = None,
) -> SessionOutcome:
    """Calibrate one recording and write ``<out>/<stem>.calibration.json``.

    Never raises for bad input: the outcome carries the error instead.
    ``provenance`` is stored in the JSON (the batch runner's up-to-date check).
    ``durable=False`` skips the per-file fsyncs (the batch syncs once at the end);
    the files are still written atomically.  ``stem`` names the outputs
    (default :func:`session_stem`; a batch passes unique ones).
    """
    from wheelcal.io import read_recording
    from wheelcal.io.calibration_json import write_calibration

    source = str(path)
    stem = stem or session_stem(path)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    try:
        recording = read_recording(
            path, topic=options.topic, info_overrides=options.info_overrides()
        )
        timings["read"] = time.perf_counter() - t0
        t1 = time.perf_counter()
        windowed, window, reason = free_spin(recording, options)
        timings["window"] = time.perf_counter() - t1
        t1 = time.perf_counter()
        result = options.fitter().fit(windowed)
        check_turns(result)
        timings["fit"] = time.perf_counter() - t1
        t1 = time.perf_counter()
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        # The .rrd first: the calibration JSON marks a complete session (the batch's
        # up-to-date check), so it is written last.
        diagnosis = diagnosis_path = None
        if options.diagnose:
            from wheelcal.diagnose.closed_loop import ClosedLoop
            from wheelcal.io.diagnosis_json import write_diagnosis

            loop = ClosedLoop(fit=options.fitter(), alpha=options.alpha)
            diagnosis = loop.run(windowed, base=result)
            timings["diagnose"] = time.perf_counter() - t1
            t1 = time.perf_counter()
            result = diagnosis.final
        # The .rrd first: the calibration JSON marks a complete session (the batch's
        # up-to-date check), so it is written last.
        rrd_path = None
        if options.rrd:
            rrd_path = _write_rrd(
                out / f"{stem}.rrd", result, recording, window, diagnosis, durable
            )
            timings["rrd"] = time.perf_counter() - t1
            t1 = time.perf_counter()
        if diagnosis is not None:
            diagnosis_path = str(
                write_diagnosis(out / f"{stem}.diagnosis.json", diagnosis, durable=durable)
            )
        json_path = write_calibration(
            out / f"{stem}.calibration.json",
            result,
            options.geometry,
            provenance,
            durable,
            window_reason=reason,
        )
        timings["write"] = time.perf_counter() - t1
    except (RecordingError, ValueError, ArithmeticError, OSError, np.linalg.LinAlgError) as exc:
        message = str(exc)
        if source not in message:
            message = f"{source}: {message}"
        refused = exc if isinstance(exc, CalibrationRefused) else None
        return SessionOutcome(
            source=source,
            stem=stem,
            error=message,
            timings_s=timings,
            gate=refused.gate if refused else None,
            fix=refused.fix if refused else None,
        )
    return SessionOutcome(
        source=source,
        stem=stem,
        result=result,
        window=window,
        window_reason=reason,
        calibration_path=str(json_path),
        diagnosis=diagnosis,
        diagnosis_path=diagnosis_path,
        rrd_path=None if rrd_path is None else str(rrd_path),
        timings_s=timings,
    )
