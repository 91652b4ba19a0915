"""The typed recording that sits between I/O and estimation.

A :class:`Recording` is validated once, at construction: strictly increasing,
finite times (s, relative to ``epoch_unix_ns``), finite samples (N, 3) in m/s²,
and the session facts the estimator needs (:class:`SessionInfo`).  Readers
repair what can be repaired (duplicate stamps, NaNs, clipped samples) *before*
building one and record what they did in ``notes``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from wheelcal.model.parameters import STANDARD_GRAVITY_MPS2

DEFAULT_RADIUS_STD_M = 1e-3
#: Session facts a user may give (file metadata, command line, pipeline file).
SESSION_FACT_KEYS = (
    "radius_m",
    "radius_std_m",
    "gravity_mps2",
    "full_scale_g",
    "sensor_id",
    "mounting_id",
)


class RecordingError(ValueError):
    """A recording that cannot be calibrated, with the reason in words."""


class CalibrationRefused(RecordingError):
    """A calibration was computed but fails a plausibility gate, so it is not given out.

    ``gate`` names the check (e.g. ``"gain_range"``), ``reason`` says what was
    seen and ``fix`` the likely remedy; ``str()`` is the whole message, naming
    the file.
    """

    def __init__(self, source: str, gate: str, reason: str, fix: str = "") -> None:
        self.source = source
        self.gate = gate
        self.reason = reason
        self.fix = fix
        text = f"{source}: refused ({gate}): {reason}"
        super().__init__(text + (f" — {fix}" if fix else ""))


@dataclass(frozen=True)
class SessionInfo:
    """Facts about a session that the data cannot tell (CONTRACT: ``wheelcal.session``)."""

    radius_m: float | None = None
    radius_std_m: float = DEFAULT_RADIUS_STD_M
    sensor_id: str = ""
    mounting_id: str = ""
    gravity_mps2: float | None = None
    full_scale_g: float | None = None
    extra: tuple[tuple[str, str], ...] = ()
    #: The user insists on a gravity outside Earth's range (``--force-gravity``).
    gravity_forced: bool = False

    def __post_init__(self) -> None:
        if self.radius_m is not None and not (np.isfinite(self.radius_m) and self.radius_m > 0):
            raise RecordingError(
                f"radius_m must be a positive number of metres, got {self.radius_m}"
            )
        if not (np.isfinite(self.radius_std_m) and self.radius_std_m >= 0):
            raise RecordingError(f"radius_std_m must be >= 0, got {self.radius_std_m}")
        if self.gravity_mps2 is not None and not (
            9.7 <= self.gravity_mps2 <= 9.9
            or (self.gravity_forced and np.isfinite(self.gravity_mps2) and self.gravity_mps2 > 0)
        ):
            raise RecordingError(
                f"gravity_mps2 = {self.gravity_mps2} is not a value of g on Earth (9.7–9.9 m/s²)"
            )

    @property
    def gravity_or_standard_mps2(self) -> float:
        """Local gravity if the session gives it, else standard gravity."""
        return STANDARD_GRAVITY_MPS2 if self.gravity_mps2 is None else float(self.gravity_mps2)

    def merged(self, **overrides) -> SessionInfo:
        """A copy where every override that is not None replaces the stored value."""
        return replace(self, **{k: v for k, v in overrides.items() if v is not None})


@dataclass(frozen=True, eq=False)
class Recording:
    """Accelerometer samples of one session, in SI units."""

    time_s: np.ndarray
    accel_mps2: np.ndarray
    info: SessionInfo = field(default_factory=SessionInfo)
    epoch_unix_ns: int = 0
    source: str = "<memory>"
    topic: str = ""
    notes: tuple[str, ...] = ()
    #: Where the reader found the sensor clipping: (3, 2) low/high rail per axis in
    #: m/s², NaN where none; None when nothing clipped.  Clipped samples are already
    #: gone; the estimator also leaves out what the model predicts near a rail.
    clip_limits_mps2: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.clip_limits_mps2 is not None:
            limits = np.array(self.clip_limits_mps2, dtype=float).reshape(3, 2)
            limits.setflags(write=False)
            object.__setattr__(self, "clip_limits_mps2", limits)
        t = np.array(self.time_s, dtype=float).reshape(-1)
        a = np.array(self.accel_mps2, dtype=float)
        if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] != t.size:
            raise RecordingError(
                f"{self.source}: need N times and (N, 3) samples, got {t.shape} and {a.shape}"
            )
        if t.size < 2:
            raise RecordingError(f"{self.source}: fewer than two samples")
        if not np.all(np.isfinite(t)):
            raise RecordingError(f"{self.source}: non-finite timestamps")
        if not np.all(np.diff(t) > 0):
            raise RecordingError(f"{self.source}: timestamps are not strictly increasing")
        if not np.all(np.isfinite(a)):
            raise RecordingError(f"{self.source}: non-finite samples (NaN or inf)")
        t.setflags(write=False)
        a.setflags(write=False)
        object.__setattr__(self, "time_s", t)
        object.__setattr__(self, "accel_mps2", a)
        object.__setattr__(self, "epoch_unix_ns", int(self.epoch_unix_ns))
        object.__setattr__(self, "notes", tuple(self.notes))

    @property
    def samples(self) -> int:
        """Number of samples."""
        return self.time_s.size

    @property
    def duration_s(self) -> float:
        """Time from first to last sample."""
        return float(self.time_s[-1] - self.time_s[0])

    @property
    def rate_hz(self) -> float:
        """Median sampling rate."""
        return float(1.0 / np.median(np.diff(self.time_s)))

    def select(self, keep: np.ndarray) -> Recording:
        """The samples where ``keep`` (bool per sample) is True."""
        keep = np.asarray(keep, dtype=bool)
        if keep.sum() < 2:
            raise RecordingError(f"{self.source}: fewer than two samples left")
        return replace(self, time_s=self.time_s[keep], accel_mps2=self.accel_mps2[keep])

    def window(self, start_s: float, end_s: float) -> Recording:
        """The samples with start_s <= t <= end_s (times keep their epoch)."""
        keep = (self.time_s >= start_s) & (self.time_s <= end_s)
        if keep.sum() < 2:
            raise RecordingError(
                f"{self.source}: window [{start_s:.3f}, {end_s:.3f}] s holds fewer than two samples"
            )
        return replace(self, time_s=self.time_s[keep], accel_mps2=self.accel_mps2[keep])
