"""One session end to end: read → gated calibration (→ closed loop) → files.

Used by ``wheelcal calibrate``, ``diagnose`` and the batch runner, so all
behave the same.  Computing and writing are separate:

* :func:`compute_session` reads the recording and runs
  :class:`~wheelcal.estimate.session_fit.SessionFit` (window, joint fit,
  plausibility gates) and, if asked, the closed loop — no files;
* :func:`write_session` writes the ``.rrd``, the diagnosis and, last, the
  calibration JSON (it marks a complete session for the batch's up-to-date
  check);
* :func:`calibrate_session` does both and never raises for bad input: the
  outcome carries the error (naming the file), the refusing gate and its fix.
  A failed session leaves no calibration: one from an earlier successful run
  of the same file is renamed ``<stem>.calibration.stale.json`` (likewise
  its ``.diagnosis.json`` and ``.rrd``), and the error says so.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from wheelcal.estimate.gates import Gates
from wheelcal.estimate.joint import JointFit
from wheelcal.estimate.result import CalibrationResult
from wheelcal.estimate.session_fit import SessionFit, WindowChoice
from wheelcal.estimate.window import FreeSpinWindow
from wheelcal.io.file_kind import special_file_kind
from wheelcal.recording import (
    SESSION_FACT_KEYS,
    CalibrationRefused,
    Recording,
    RecordingError,
)

#: Outputs of a session, renamed ``<stem>.<kind>.stale.<ext>`` when a re-run fails.
_OUTPUT_SUFFIXES = (".calibration.json", ".diagnosis.json", ".rrd")
#: Local gravity on Earth lies in this range; outside it needs ``force_gravity``.
EARTH_GRAVITY_RANGE_MPS2 = (9.7, 9.9)
#: What a calibration fits: the closed loop's final model, or the paper's bare model.
MODELS = ("closed_loop", "paper")


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
    geometry: str = "radius"
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
        """The joint-fit configuration for these options."""
        return JointFit(
            geometry=self.geometry,
            known_tilt_deg=self.known_tilt_deg,
            tilt_std_deg=self.tilt_std_deg,
            use_gyro=self.geometry == "rolling",  # the yaw rate comes from the gyro
            gyro_g_prior_dps_per_g=self.gyro_g_sensitivity_dps_per_g,
        )

    def session_fit(self) -> SessionFit:
        """Window, joint fit, closed loop (unless ``model="paper"``) and gates."""
        loop = None
        if self.model == "closed_loop":
            from wheelcal.diagnose.closed_loop import ClosedLoop

            loop = ClosedLoop(fit=self.fitter(), alpha=self.alpha)
        return SessionFit(
            fitter=self.fitter(),
            gates=self.gates,
            start_s=self.start_s,
            end_s=self.end_s,
            gyro=self.gyro,
            closed_loop=loop,
        )


def _positive(what: str, value: float | None, unit: str) -> None:
    if value is not None and not (np.isfinite(value) and value > 0):
        raise ValueError(f"{what} must be a positive number of {unit}, got {value}")


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
    #: The whole recording (for the .rrd); None after a failure.
    recording: Recording | None = None

    @property
    def ok(self) -> bool:
        """True when the session was calibrated (and, after writing, written)."""
        return self.error is None


def session_stem(path: str | Path) -> str:
    """Output stem of a recording: its file name without ``.mcap``."""
    name = Path(path).name
    return name[: -len(".mcap")] if name.endswith(".mcap") else Path(path).stem


def compute_session(path: str | Path, options: SessionOptions) -> SessionOutcome:
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
) -> SessionOutcome:
    """Calibrate a recording already read and checked (see :func:`compute_session`)."""
    timings = dict(timings or {})
    t1 = time.perf_counter()
    fit = options.session_fit().run(recording)
    timings["fit"] = time.perf_counter() - t1
    return _outcome_of(recording.source, fit.result, fit.window, fit.diagnosis, recording, timings)


def _outcome_of(source, result, choice: WindowChoice, diagnosis, recording, timings):
    return SessionOutcome(
        source=source,
        stem=session_stem(source),
        result=result,
        window=choice.found,
        window_reason=choice.reason,
        diagnosis=diagnosis,
        recording=recording,
        timings_s=timings,
    )


def _write_rrd(path: Path, result, recording, window, diagnosis, durable: bool = True) -> Path:
    """Session .rrd; with a diagnosis that added effects, its before/after tab.

    A closed loop's final fit is assessed anew, without the gyroscope's
    calibration of the first fit: that one is passed on for the measured ω.
    """
    from wheelcal.viz.session_rrd import write_session_rrd

    gyro = None
    if diagnosis is not None and diagnosis.base.assessment is not None:
        gyro = diagnosis.base.assessment.gyro
    return write_session_rrd(
        path, result, recording, window, durable, diagnosis=diagnosis, gyro_calibration=gyro
    )


def write_session(
    outcome: SessionOutcome,
    options: SessionOptions,
    out_dir: str | Path,
    provenance: dict | None = None,
    durable: bool = True,
) -> SessionOutcome:
    """Write a computed session's files; returns the outcome with their paths."""
    from wheelcal.io.calibration_json import write_calibration

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    timings = dict(outcome.timings_s)
    t1 = time.perf_counter()
    stem = outcome.stem
    # The .rrd first: the calibration JSON marks a complete session (the batch's
    # up-to-date check), so it is written last.
    rrd_path = diagnosis_path = None
    if options.rrd:
        rrd_path = str(
            _write_rrd(
                out / f"{stem}.rrd",
                outcome.result,
                outcome.recording,
                outcome.window,
                outcome.diagnosis,
                durable,
            )
        )
        timings["rrd"] = time.perf_counter() - t1
        t1 = time.perf_counter()
    if options.diagnose and outcome.diagnosis is not None:
        from wheelcal.io.diagnosis_json import write_diagnosis

        diagnosis_path = str(
            write_diagnosis(out / f"{stem}.diagnosis.json", outcome.diagnosis, durable=durable)
        )
    json_path = write_calibration(
        out / f"{stem}.calibration.json",
        outcome.result,
        options.geometry,
        provenance,
        durable,
        window_reason=outcome.window_reason,
        model=options.model,
        diagnosis=outcome.diagnosis,
    )
    timings["write"] = time.perf_counter() - t1
    return replace(
        outcome,
        calibration_path=str(json_path),
        diagnosis_path=diagnosis_path,
        rrd_path=rrd_path,
        timings_s=timings,
    )


def calibrate_session(
    path: str | Path,
    options: SessionOptions,
    out_dir: str | Path,
    provenance: dict | None = None,
    durable: bool = True,
    stem: str | None = None,
) -> SessionOutcome:
    """Calibrate one recording and write ``<out>/<stem>.calibration.json``.

    Never raises for bad input: the outcome carries the error instead, and no
    calibration of this file is left in ``out_dir`` (an earlier one is renamed
    ``.stale``).  ``provenance`` is stored in the JSON (the batch runner's
    up-to-date check).  ``durable=False`` skips the per-file fsyncs (the batch
    syncs once at the end); the files are still written atomically.  ``stem``
    names the outputs (default :func:`session_stem`; a batch passes unique ones).
    """
    source = str(path)
    stem = stem or session_stem(path)
    try:
        outcome = replace(compute_session(path, options), stem=stem)  # the reader refuses FIFOs
        return write_session(outcome, options, out_dir, provenance, durable)
    except (RecordingError, ValueError, ArithmeticError, OSError, np.linalg.LinAlgError) as exc:
        return failed_outcome(source, stem, out_dir, describe_error(exc), exc)
    except (MemoryError, RecursionError) as exc:
        # A recording that exhausts memory or the stack fails alone: the next one still runs.
        what = "out of memory" if isinstance(exc, MemoryError) else "input nested too deeply"
        return failed_outcome(source, stem, out_dir, f"{what} ({type(exc).__name__})", exc)
    except Exception as exc:  # one session must never stop the others
        return failed_outcome(
            source, stem, out_dir, f"unexpected error: {type(exc).__name__}: {exc}", exc
        )


def describe_error(exc: BaseException) -> str:
    """An error in words: ``path: Permission denied`` rather than ``[Errno 13] …: 'path'``."""
    if isinstance(exc, OSError) and exc.strerror:
        if exc.filename is None:
            return exc.strerror
        where = f"{exc.filename} -> {exc.filename2}" if exc.filename2 else f"{exc.filename}"
        return f"{where}: {exc.strerror}"
    return str(exc)


def check_regular_file(path: str | Path) -> None:
    """Refuse a device, FIFO or folder before reading it (``/dev/zero`` never ends).

    A missing file is left to the reader, which names it.
    """
    kind = special_file_kind(path)
    if kind is not None:
        raise RecordingError(f"{path}: is {kind}, not a recording file; give an .mcap file")


def failed_outcome(
    source: str, stem: str, out_dir: str | Path, message: str, exc: BaseException | None = None
) -> SessionOutcome:
    """The outcome of a failed session: the error names the file; earlier outputs go stale."""
    if source not in message:
        message = f"{source}: {message}"
    stale = keep_as_stale(Path(out_dir), stem)
    if stale:
        message += f" (the earlier outputs of this file were kept as {stale})"
    refused = exc if isinstance(exc, CalibrationRefused) else None
    return SessionOutcome(
        source=source,
        stem=stem,
        error=message,
        gate=refused.gate if refused else None,
        fix=refused.fix if refused else None,
    )


def keep_as_stale(out: Path, stem: str) -> str | None:
    """Rename a failed session's earlier outputs to ``.stale``; their new names, or None.

    Never deletes: a good earlier result stays on disk, marked so nobody takes it
    for this run's.
    """
    kept = []
    for suffix in _OUTPUT_SUFFIXES:
        old = out / f"{stem}{suffix}"
        if not old.exists():
            continue
        kind, _, ext = suffix.rpartition(".")
        new = out / f"{stem}{kind}.stale.{ext}"
        try:
            os.replace(old, new)
        except OSError:
            continue
        kept.append(new.name)
    return ", ".join(kept) or None
