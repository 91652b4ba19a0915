"""The typed recording that sits between I/O and estimation.

A :class:`Recording` is validated once, at construction: strictly increasing,
finite times (s, relative to ``epoch_unix_ns``), finite samples (N, 3) in m/s²,
and the session facts the estimator needs (:class:`SessionInfo`).  Readers
repair what can be repaired (duplicate stamps, NaNs, clipped samples) *before*
building one and record what they did in ``notes``.

Optional channels on the accelerometer's clock (additive, issue 13):

* ``gyro_radps`` (N, 3), rad/s, in the gyro's own axes (which sit close to,
  not exactly on, the accelerometer's).  **A row of NaN marks a sample whose
  gyro reading must be left out** — clipped at the gyro's full scale, NaN in
  the file, or absent from that message — while its accelerometer sample
  stays; :attr:`Recording.gyro_valid` is the mask of usable rows.  A row is
  either all finite or all NaN (never partly), and ``inf`` is refused.
  Sign (CONTRACT bench frame): the wheel turns at Ω = −ω e_Z, so an ideal
  gyro reads −ω R e_Z (R maps bench → sensor).
* ``temperature_c`` (N,), °C, finite: the sensor's temperature interpolated
  onto the sample times.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from wheelcal.model.parameters import STANDARD_GRAVITY_MPS2
from wheelcal.recording.errors import CalibrationRefused, RecordingError  # noqa: F401

DEFAULT_RADIUS_STD_M = 1e-3
#: Session facts a user may give (file metadata, command line, pipeline file).
SESSION_FACT_KEYS = (
    "radius_m",
    "radius_std_m",
    "gravity_mps2",
    "full_scale_g",
    "gyro_full_scale_dps",
    "sensor_id",
    "mounting_id",
)


def _frozen_or_copy(values) -> np.ndarray:
    """A float64 array the recording can keep: a read-only float64 array as it is, else a copy.

    Read-only arrays are taken without a copy (a 2.9 M-sample recording is
    70 MB per copy): whoever passes one promises not to change its memory
    through another view.  The reader hands over its arrays this way.
    """
    if isinstance(values, np.ndarray) and values.dtype == np.float64 and not values.flags.writeable:
        return values
    return np.array(values, dtype=float)


@dataclass(frozen=True)
class SessionInfo:
    """Facts about a session that the data cannot tell (CONTRACT: ``wheelcal.session``)."""

    radius_m: float | None = None
    radius_std_m: float = DEFAULT_RADIUS_STD_M
    sensor_id: str = ""
    mounting_id: str = ""
    gravity_mps2: float | None = None
    full_scale_g: float | None = None
    #: The gyroscope's range (±°/s) if known: readings at it are clipped.
    gyro_full_scale_dps: float | None = None
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
        fs = self.gyro_full_scale_dps
        if fs is not None and not (np.isfinite(fs) and fs > 0):
            raise RecordingError(f"gyro_full_scale_dps must be a positive number, got {fs}")

    @property
    def gravity_or_standard_mps2(self) -> float:
        """Local gravity if the session gives it, else standard gravity."""
        return STANDARD_GRAVITY_MPS2 if self.gravity_mps2 is None else float(self.gravity_mps2)

    def merged(self, **overrides) -> SessionInfo:
        """A copy where every override that is not None replaces the stored value."""
        return replace(self, **{k: v for k, v in overrides.items() if v is not None})


@dataclass(frozen=True, eq=False)
class Recording:
    """Accelerometer samples of one session, in SI units, and optional gyro and temperature.

    Attributes
    ----------
    time_s:
        (N,) strictly increasing, s from ``epoch_unix_ns``.
    accel_mps2:
        (N, 3) accelerometer samples, m/s², finite.
    gyro_radps:
        ``None`` (no gyroscope) or (N, 3) angular rate in rad/s on the same
        clock, in the gyro's axes; a row of NaN = left out (clipped, NaN or
        absent in the file), see :attr:`gyro_valid`.  Sign: an ideal gyro on
        the wheel reads −ω R e_Z (module docstring).
    temperature_c:
        ``None`` or (N,) sensor temperature in °C at the sample times, finite.
    """

    time_s: np.ndarray
    accel_mps2: np.ndarray
    info: SessionInfo = field(default_factory=SessionInfo)
    epoch_unix_ns: int = 0
    source: str = "<memory>"
    topic: str = ""
    notes: tuple[str, ...] = ()
    gyro_radps: np.ndarray | None = None
    temperature_c: np.ndarray | None = None
    #: Where the reader found the sensor clipping: (3, 2) low/high rail per axis in
    #: m/s², NaN where none; None when nothing clipped.  Clipped samples are already
    #: gone; the estimator also leaves out what the model predicts near a rail.
    clip_limits_mps2: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.clip_limits_mps2 is not None:
            limits = np.array(self.clip_limits_mps2, dtype=float).reshape(3, 2)
            limits.setflags(write=False)
            object.__setattr__(self, "clip_limits_mps2", limits)
        t = _frozen_or_copy(self.time_s).reshape(-1)
        a = _frozen_or_copy(self.accel_mps2)
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
        if self.gyro_radps is not None:
            object.__setattr__(self, "gyro_radps", self._checked_gyro(t.size))
        if self.temperature_c is not None:
            object.__setattr__(self, "temperature_c", self._checked_temperature(t.size))

    def _checked_gyro(self, n: int) -> np.ndarray:
        w = _frozen_or_copy(self.gyro_radps)
        if w.shape != (n, 3):
            raise RecordingError(
                f"{self.source}: gyro_radps must be (N, 3) = ({n}, 3), got {w.shape}"
            )
        finite = np.isfinite(w)
        if np.any(np.isinf(w)):
            raise RecordingError(f"{self.source}: gyro_radps holds inf (use NaN rows to leave out)")
        partial = finite.any(axis=1) & ~finite.all(axis=1)
        if np.any(partial):
            raise RecordingError(
                f"{self.source}: gyro_radps row {int(np.argmax(partial))} is partly NaN; "
                "a row is either all finite or all NaN (left out)"
            )
        w.setflags(write=False)
        return w

    def _checked_temperature(self, n: int) -> np.ndarray:
        temp = _frozen_or_copy(self.temperature_c).reshape(-1)
        if temp.size != n:
            raise RecordingError(
                f"{self.source}: temperature_c needs one value per sample ({n}), got {temp.size}"
            )
        if not np.all(np.isfinite(temp)):
            raise RecordingError(f"{self.source}: temperature_c holds NaN or inf")
        temp.setflags(write=False)
        return temp

    @property
    def has_gyro(self) -> bool:
        """Whether the recording carries a gyroscope channel."""
        return self.gyro_radps is not None

    @property
    def gyro_valid(self) -> np.ndarray:
        """(N,) True where the gyro row is usable (all False without a gyro)."""
        if self.gyro_radps is None:
            return np.zeros(self.time_s.size, dtype=bool)
        return np.isfinite(self.gyro_radps[:, 0])

    @property
    def samples(self) -> int:
        """Number of samples."""
        return self.time_s.size

    @property
    def duration_s(self) -> float:
        """Time from first to last sample."""
        return float(self.time_s[-1] - self.time_s[0])

    @cached_property
    def rate_hz(self) -> float:
        """Median sampling rate (computed once: the times never change after construction).

        ``window``, ``select`` and ``dataclasses.replace`` build a new recording,
        which computes its own.
        """
        return float(1.0 / np.median(np.diff(self.time_s)))

    def select(self, keep: np.ndarray) -> Recording:
        """The samples where ``keep`` (bool per sample) is True, every channel."""
        keep = np.asarray(keep, dtype=bool)
        if keep.sum() < 2:
            raise RecordingError(f"{self.source}: fewer than two samples left")
        return self._take(keep)

    def window(self, start_s: float, end_s: float) -> Recording:
        """The samples with start_s <= t <= end_s (times keep their epoch), every channel."""
        # Times increase strictly: the window is one slice, and its arrays are read-only
        # views of this recording's (no copy, see _frozen_or_copy).
        lo = int(np.searchsorted(self.time_s, start_s, side="left"))
        hi = int(np.searchsorted(self.time_s, end_s, side="right"))
        if hi - lo < 2:
            raise RecordingError(
                f"{self.source}: window [{start_s:.3f}, {end_s:.3f}] s holds fewer than two samples"
            )
        return self._take(slice(lo, hi))

    def _take(self, index: np.ndarray | slice) -> Recording:
        """Every channel at ``index`` (a mask copies; a slice keeps read-only views)."""
        return replace(
            self,
            time_s=self.time_s[index],
            accel_mps2=self.accel_mps2[index],
            gyro_radps=None if self.gyro_radps is None else self.gyro_radps[index],
            temperature_c=None if self.temperature_c is None else self.temperature_c[index],
        )
