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

Two ways in, one set of checks: the constructor takes samples already checked
and checks only the invariants above (cheap: shapes, finite values, strictly
increasing times), raising :class:`RecordingError` naming ``source``;
:meth:`Recording.from_samples` takes raw samples — any order, any unit the
contract names, defects and all — through the repairs and refusals of
:mod:`.samples`, :mod:`.gyro` and :mod:`.temperature` first.  Every reader and
``wheelcal.calibrate(recording)`` build their recording with it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from wheelcal.model import STANDARD_GRAVITY_MPS2
from wheelcal.recording.errors import CalibrationRefused, RecordingError  # noqa: F401
from wheelcal.recording.gyro import RADPS_PER_DPS, align_to_samples, check_gyro
from wheelcal.recording.samples import CleanSamples, InputPolicy, clean_samples
from wheelcal.recording.temperature import TemperatureReadings, temperature_at

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
#: Units of accelerometer samples a source may state (CONTRACT: ``g`` is 9.80665 m/s²).
ACCEL_UNITS = ("m/s^2", "g")
#: Units of gyroscope samples a source may state.
GYRO_UNITS = ("rad/s", "deg/s")


def _frozen_or_copy(values, source: str, name: str) -> np.ndarray:
    """A float64 array the recording can keep: a read-only float64 array as it is, else a copy.

    Read-only arrays are taken without a copy (a 2.9 M-sample recording is
    70 MB per copy): whoever passes one promises not to change its memory
    through another view.  The reader hands over its arrays this way.
    Anything but real numbers is a :class:`RecordingError` naming ``source``.
    """
    if isinstance(values, np.ndarray) and values.dtype == np.float64 and not values.flags.writeable:
        return values
    if isinstance(values, np.ndarray) and values.dtype.kind not in "biuf":
        raise RecordingError(f"{source}: {name} must be real numbers, not {values.dtype}")
    try:
        return np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise RecordingError(f"{source}: {name} must be real numbers") from None


def _accel_in_mps2(label: str, accel, unit: str, consume: bool, notes: list[str]) -> np.ndarray:
    """The samples in m/s² (in place when they are the caller's to give away)."""
    if unit not in ACCEL_UNITS:
        raise RecordingError(f"{label}: unit {unit!r} is not one of {list(ACCEL_UNITS)}")
    if unit != "g":
        return accel
    notes.append("samples converted from g (9.80665 m/s²)")
    owned = consume and isinstance(accel, np.ndarray) and accel.dtype == np.float64
    if owned and accel.flags.writeable:
        return np.multiply(accel, STANDARD_GRAVITY_MPS2, out=accel)
    return np.multiply(accel, STANDARD_GRAVITY_MPS2)


def _gyro_in_radps(label: str, gyro, unit: str, notes: list[str]) -> np.ndarray:
    """The gyro rows in rad/s."""
    if unit not in GYRO_UNITS:
        raise RecordingError(f"{label}: gyro unit {unit!r} is not one of {list(GYRO_UNITS)}")
    if unit != "deg/s":
        return gyro
    notes.append("gyro converted from deg/s")
    return np.multiply(gyro, RADPS_PER_DPS)


def _seconds_since(time_ns: np.ndarray, epoch_ns: int) -> np.ndarray:
    """Read-only seconds since ``epoch_ns``, computed in the stamps' own memory (consumed).

    (A 2.9 M-sample recording's stamps and seconds would otherwise coexist.)
    """
    if not (time_ns.flags.writeable and time_ns.flags.c_contiguous):
        time_ns = np.array(time_ns, dtype=np.int64)
    time_ns -= epoch_ns
    seconds = time_ns.view(np.float64)
    np.multiply(time_ns, 1e-9, out=seconds, casting="unsafe")
    seconds.setflags(write=False)
    return seconds


def _gyro_on_kept(label, raw, radps, info, unit_hint, notes) -> np.ndarray | None:
    """The gyro rows of the kept samples, judged (``raw``: stamps, samples, kept stamps)."""
    if radps is None:
        return None
    time_ns, accel, kept_ns = raw
    aligned = align_to_samples(time_ns, accel, radps, kept_ns)  # the same repairs
    gyro, gyro_notes = check_gyro(label, aligned, info.gyro_full_scale_dps, unit_hint=unit_hint)
    notes += gyro_notes
    return gyro


def _temperature_on_kept(raw, temperature, notes) -> np.ndarray | None:
    """The temperature at the kept stamps: readings interpolated, or one per sample followed."""
    time_ns, accel, kept_ns = raw
    if isinstance(temperature, TemperatureReadings):
        values, temperature_notes = temperature_at(
            temperature.what, temperature.stamp_ns, temperature.values_c, kept_ns
        )
        notes += temperature_notes
        return values
    if temperature is None:
        return None
    column = np.asarray(temperature, dtype=float).reshape(-1, 1)
    return align_to_samples(time_ns, accel, column, kept_ns)[:, 0]  # as the gyro


def _kept_columns(clean: CleanSamples, given_ns, given_accel, consume: bool) -> dict:
    """The kept samples as a recording's columns: s since the first kept stamp, read-only.

    Without a copy where the arrays are ours (:func:`_frozen_or_copy`): made by
    the checks, or handed over (``consume``); the caller's are never changed.
    """
    kept_ns, accel = clean.time_ns, clean.accel_mps2
    if not consume and np.may_share_memory(kept_ns, given_ns):
        kept_ns = np.array(kept_ns, dtype=np.int64)
    if consume or not np.may_share_memory(accel, given_accel):
        accel.setflags(write=False)
    epoch = int(kept_ns[0])
    return {
        "time_s": _seconds_since(kept_ns, epoch),
        "accel_mps2": accel,
        "epoch_unix_ns": epoch,
        "clip_limits_mps2": clean.clip_limits_mps2,
        **(
            {
                "clipped_time_s": (clean.clipped_ns - epoch) * 1e-9,
                "clipped_mps2": clean.clipped_mps2,
            }
            if clean.clipped_ns is not None
            else {}
        ),
    }


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
    #: The clipped samples the reader dropped (their times, s from ``epoch_unix_ns``, and
    #: readings, m/s²), kept for the views to mark; never fitted.  None: none dropped.
    clipped_time_s: np.ndarray | None = None
    clipped_mps2: np.ndarray | None = None

    def __post_init__(self) -> None:
        """The invariants (cheap: no repair, one pass per check), or :class:`RecordingError`."""
        if not isinstance(self.info, SessionInfo):
            raise RecordingError(f"{self.source}: info must be a SessionInfo, got {self.info!r}")
        if self.clip_limits_mps2 is not None:
            limits = _frozen_or_copy(self.clip_limits_mps2, self.source, "clip_limits_mps2")
            if limits.size != 6:
                raise RecordingError(
                    f"{self.source}: clip_limits_mps2 must be (3, 2), got {limits.shape}"
                )
            limits = limits.reshape(3, 2)
            limits.setflags(write=False)
            object.__setattr__(self, "clip_limits_mps2", limits)
        if (self.clipped_time_s is None) != (self.clipped_mps2 is None):
            raise RecordingError(f"{self.source}: clipped_time_s and clipped_mps2 go together")
        if self.clipped_time_s is not None:
            ct = _frozen_or_copy(self.clipped_time_s, self.source, "clipped_time_s").reshape(-1)
            ca = _frozen_or_copy(self.clipped_mps2, self.source, "clipped_mps2")
            if ca.shape != (ct.size, 3):
                raise RecordingError(
                    f"{self.source}: clipped_mps2 must be (K, 3) for K clipped times"
                )
            ct.setflags(write=False)
            ca.setflags(write=False)
            object.__setattr__(self, "clipped_time_s", ct)
            object.__setattr__(self, "clipped_mps2", ca)
        t = _frozen_or_copy(self.time_s, self.source, "time_s").reshape(-1)
        a = _frozen_or_copy(self.accel_mps2, self.source, "accel_mps2")
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
        w = _frozen_or_copy(self.gyro_radps, self.source, "gyro_radps")
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
        temp = _frozen_or_copy(self.temperature_c, self.source, "temperature_c").reshape(-1)
        if temp.size != n:
            raise RecordingError(
                f"{self.source}: temperature_c needs one value per sample ({n}), got {temp.size}"
            )
        if not np.all(np.isfinite(temp)):
            raise RecordingError(f"{self.source}: temperature_c holds NaN or inf")
        temp.setflags(write=False)
        return temp

    @classmethod
    def from_samples(
        cls,
        *,
        source: str,
        time_ns: np.ndarray,
        accel: np.ndarray,
        unit: str = "m/s^2",
        info: SessionInfo | None = None,
        policy: InputPolicy | None = None,
        gyro: np.ndarray | None = None,
        gyro_unit: str = "rad/s",
        temperature: TemperatureReadings | np.ndarray | None = None,
        topic: str = "",
        notes: Sequence[str] = (),
        label: str | None = None,
        unit_remedy: str | None = None,
        gyro_unit_hint: str = "",
        consume: bool = False,
        unit_stated_by: str = "the file",
    ) -> Recording:
        """A checked recording from raw samples: repaired where that invents nothing, or refused.

        The one way in for raw samples (every reader; :meth:`checked`): SI units,
        then :func:`~wheelcal.recording.samples.clean_samples` (its table: what is
        repaired, what refused); gyro rows follow the repairs by stamp and are judged
        by :func:`~wheelcal.recording.gyro.check_gyro`; the temperature goes onto the
        kept stamps.  Times: s from the first kept stamp.

        Parameters
        ----------
        source, topic:
            The file (or ``"<memory>"``) and the topic, kept by the recording.
        time_ns, accel, unit:
            (N,) int64 stamps in any order; (N, 3) samples in ``unit``: ``"m/s^2"``,
            or ``"g"`` (converted, noted, and what the unit check holds them to).
        info, policy:
            The session's facts (its ranges find clipping); the thresholds of
            repair and refusal (:class:`~wheelcal.recording.samples.InputPolicy`).
        gyro, gyro_unit:
            ``None`` or (N, 3) rows on the same stamps (NaN: no reading), in
            ``"rad/s"`` or ``"deg/s"`` (converted and noted).
        temperature:
            :class:`~wheelcal.recording.temperature.TemperatureReadings` on their own
            clock (judged and interpolated), or (N,) °C, one per sample.
        notes:
            What the source already says about the samples; the repairs' follow.
        label, unit_remedy, gyro_unit_hint:
            How messages name the samples (default ``source``), and how to state
            the units right in this source's format.
        unit_stated_by:
            Who claimed ``unit`` (``"the file"``, or the option that overrode it),
            for the unit check's message.
        consume:
            ``time_ns`` and ``accel`` are the caller's to give away (a reader's
            decoded columns): converted and kept in place, no copy.

        Raises
        ------
        RecordingError
            Naming ``label``: samples the checks refuse (``SampleError``), or a
            unit not in :data:`ACCEL_UNITS` / :data:`GYRO_UNITS`.
        """
        label = source if label is None else label
        info = SessionInfo() if info is None else info
        notes = list(notes)
        mps2 = _accel_in_mps2(label, accel, unit, consume, notes)
        radps = None if gyro is None else _gyro_in_radps(label, gyro, gyro_unit, notes)
        policy = InputPolicy() if policy is None else policy
        if radps is not None:
            clipping = max(policy.max_clipped_fraction, policy.max_clipped_fraction_with_gyro)
            policy = replace(policy, max_clipped_fraction=clipping)
        clean = clean_samples(
            label,
            time_ns,
            mps2,
            unit=unit,
            full_scale_g=info.full_scale_g,
            policy=policy,
            unit_remedy=unit_remedy,
            unit_stated_by=unit_stated_by,
        )
        notes += clean.notes
        raw = (time_ns, mps2, clean.time_ns)
        gyro_radps = _gyro_on_kept(label, raw, radps, info, gyro_unit_hint, notes)
        temperature_c = _temperature_on_kept(raw, temperature, notes)
        columns = _kept_columns(clean, time_ns, accel, consume)  # consumes the kept stamps
        columns.update(gyro_radps=gyro_radps, temperature_c=temperature_c, notes=tuple(notes))
        return cls(**columns, info=info, source=source, topic=topic)

    def checked(
        self,
        *,
        unit: str | None = None,
        info: SessionInfo | None = None,
        policy: InputPolicy | None = None,
    ) -> Recording:
        """A copy through the readers' checks (:meth:`from_samples`), e.g. of one built in memory.

        ``unit="g"``: its samples are in fact in g; ``info`` replaces its facts.
        Its notes stay, the repairs' notes follow; where the checks find no clipping
        (a recording whose clipped samples a reader already dropped), its rails and
        dropped samples stay too.
        """
        checked = Recording.from_samples(
            source=self.source,
            time_ns=self.epoch_unix_ns + np.rint(self.time_s * 1e9).astype(np.int64),
            accel=self.accel_mps2,
            unit=unit or "m/s^2",
            info=self.info if info is None else info,
            policy=policy,
            gyro=self.gyro_radps,
            temperature=self.temperature_c,
            topic=self.topic,
            notes=self.notes,
            **(
                {
                    "unit_stated_by": f"accel_unit={unit!r}",
                    "unit_remedy": f"leave accel_unit={unit!r} out",
                }
                if unit is not None
                else {}
            ),
        )
        if checked.clip_limits_mps2 is not None or self.clip_limits_mps2 is None:
            return checked
        shift_s = (self.epoch_unix_ns - checked.epoch_unix_ns) * 1e-9
        return replace(
            checked,
            clip_limits_mps2=self.clip_limits_mps2,
            clipped_time_s=None if self.clipped_time_s is None else self.clipped_time_s + shift_s,
            clipped_mps2=self.clipped_mps2,
        )

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

    def thinned(self, stride: int) -> Recording:
        """Every ``stride``-th sample, every channel (views: a quick look, e.g. a fit's start)."""
        if int(stride) < 1:
            raise ValueError(f"stride must be >= 1, got {stride}")
        return self if int(stride) == 1 else self._take(slice(None, None, int(stride)))

    def _take(self, index: np.ndarray | slice) -> Recording:
        """Every channel at ``index`` (a mask copies; a slice keeps read-only views)."""
        return replace(
            self,
            time_s=self.time_s[index],
            accel_mps2=self.accel_mps2[index],
            gyro_radps=None if self.gyro_radps is None else self.gyro_radps[index],
            temperature_c=None if self.temperature_c is None else self.temperature_c[index],
        )
