"""A data logger's glitches, applied to simulated samples.

Each option is off by default; positions are drawn from the generator passed in,
after every other draw of the simulation (so the samples themselves do not
change when a glitch is switched on).

* ``gyro_spikes`` — that many isolated gyro samples replaced, on one random
  axis each, by ±``spike_radps`` (a bit error; a real drive had 3.7·10⁷ rad/s);
  never in the leading zero rows or the first and last 10 samples.
* ``leading_zero_rows`` — the first rows read exactly 0 on every axis of the
  accelerometer and the gyro (the logger wrote before the sensor's first
  reading); their stamps are kept.
* ``gap_s`` — one stretch of this length lost (no rows, the stamps jump),
  starting at a random time in the middle 20–80 % of the recording.
* ``duplicate_stamps`` — that many rows written twice in a row (the same stamp,
  the same values).  A :class:`~wheelcal.recording.Recording` cannot hold two
  equal stamps, so these exist only in the logger's raw output
  (:class:`LoggedSamples`, what a file written from it contains); the
  recording holds each row once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Glitches:
    """Which logger glitches to simulate (module docstring)."""

    gyro_spikes: int = 0
    spike_radps: tuple[float, float] = (1e7, 4e7)
    leading_zero_rows: int = 0
    gap_s: float = 0.0
    duplicate_stamps: int = 0

    def __post_init__(self) -> None:
        for name in ("gyro_spikes", "leading_zero_rows", "duplicate_stamps"):
            if int(getattr(self, name)) != getattr(self, name) or getattr(self, name) < 0:
                raise ValueError(f"{name} must be a whole number >= 0")
        low, high = self.spike_radps
        if not 0 < low <= high:
            raise ValueError(
                f"spike_radps must be (low, high) with 0 < low <= high, got {low, high}"
            )
        if not (np.isfinite(self.gap_s) and self.gap_s >= 0):
            raise ValueError(f"gap_s must be finite and >= 0, got {self.gap_s}")

    @property
    def any(self) -> bool:
        """Whether any glitch is on."""
        return bool(
            self.gyro_spikes or self.leading_zero_rows or self.gap_s or self.duplicate_stamps
        )


@dataclass(frozen=True, eq=False)
class GlitchRows:
    """Where the glitches went.

    ``kept`` (N_recording,) indexes the simulated sample grid (the rows the gap
    left); ``spike_rows`` and ``zero_rows`` index the recording's rows;
    ``gap_s`` is the lost stretch (start, end) in recording time or ``None``;
    ``duplicate_rows`` index the recording's rows that the logger wrote twice.
    """

    kept: np.ndarray
    spike_rows: np.ndarray
    zero_rows: np.ndarray
    gap_s: tuple[float, float] | None
    duplicate_rows: np.ndarray


@dataclass(frozen=True, eq=False)
class LoggedSamples:
    """The logger's raw output: stamps (int ns since the Unix epoch) and rows, glitches included."""

    time_ns: np.ndarray
    accel_mps2: np.ndarray
    gyro_radps: np.ndarray | None


def glitch_rows(
    glitches: Glitches, time_s: np.ndarray, has_gyro: bool, rng: np.random.Generator
) -> GlitchRows:
    """Draw where the glitches fall on the sample grid ``time_s``."""
    n = time_s.size
    kept = np.arange(n)
    gap = None
    if glitches.gap_s > 0:
        start = float(rng.uniform(0.2, 0.8) * time_s[-1])
        lost = (time_s >= start) & (time_s < start + glitches.gap_s)
        if lost.all() or not lost.any():
            raise ValueError(f"a gap of {glitches.gap_s:g} s does not fit this recording")
        kept = np.flatnonzero(~lost)
        gap = (start, start + glitches.gap_s)
    m = kept.size
    zeros = np.arange(min(glitches.leading_zero_rows, m))
    first = zeros.size + 10
    spikes = np.zeros(0, dtype=int)
    if glitches.gyro_spikes:
        if not has_gyro:
            raise ValueError("gyro spikes need a gyroscope")
        if m - 10 - first < glitches.gyro_spikes:
            raise ValueError("too few samples for the gyro spikes asked for")
        spikes = np.sort(rng.choice(np.arange(first, m - 10), glitches.gyro_spikes, replace=False))
    duplicates = np.zeros(0, dtype=int)
    if glitches.duplicate_stamps:
        if m - 1 - first < glitches.duplicate_stamps:
            raise ValueError("too few samples for the duplicate stamps asked for")
        pool = np.arange(first, m - 1)
        duplicates = np.sort(rng.choice(pool, glitches.duplicate_stamps, replace=False))
    return GlitchRows(kept, spikes, zeros, gap, duplicates)


def apply_glitches(
    glitches: Glitches,
    rows: GlitchRows,
    accel_mps2: np.ndarray,
    gyro_radps: np.ndarray | None,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Spikes and zero rows on the recording's rows (copies); the gap is already applied."""
    accel = np.array(accel_mps2, dtype=float)
    gyro = None if gyro_radps is None else np.array(gyro_radps, dtype=float)
    if rows.spike_rows.size:
        axes = rng.integers(0, 3, rows.spike_rows.size)
        sizes = rng.uniform(*glitches.spike_radps, rows.spike_rows.size)
        signs = rng.choice([-1.0, 1.0], rows.spike_rows.size)
        gyro[rows.spike_rows, axes] = signs * sizes
    accel[rows.zero_rows] = 0.0
    if gyro is not None:
        gyro[rows.zero_rows] = 0.0
    return accel, gyro


def logged_samples(
    time_ns: np.ndarray, accel_mps2: np.ndarray, gyro_radps: np.ndarray | None, rows: GlitchRows
) -> LoggedSamples:
    """The recording's rows as the logger wrote them: each duplicate row twice."""
    take = np.sort(np.concatenate([np.arange(time_ns.size), rows.duplicate_rows]))
    return LoggedSamples(
        time_ns=np.asarray(time_ns, dtype=np.int64)[take],
        accel_mps2=accel_mps2[take],
        gyro_radps=None if gyro_radps is None else gyro_radps[take],
    )
