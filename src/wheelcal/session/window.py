"""Find the free-spin window in a whole recording (rest, push, spin, brake, rest).

The model of eq. (1) holds only while nothing but air and bearings act on the
wheel.  The search uses what every mounting shares, without assuming which
sensor axis is which:

* In the sensor frame the gravity component g sin α (cos ϑ X + sin ϑ Y)
  *rotates* in the plane spanned by Γ R e_X and Γ R e_Y, while everything else
  (o, Γ R (r ω² e_X + r ω̇ e_Y + g cos α e_Z)) varies slowly.  A high-pass
  (zero-phase, ``highpass_hz`` well below the slowest spin) keeps the rotating
  part h(t); its plane comes from the two leading principal axes of h.
* Projected on that plane, h is a near-circle: its angle is the wheel phase ϑ
  up to a constant and a sign, its radius ≈ g sin α while the wheel turns and
  ≈ the noise while it rests.
* Phase differences over a baseline ``lag_s`` give |ω|, and differences of
  those give |ω̇|.  A free spin decays slowly (|ω̇| ≲ 0.2 rad/s² for a
  hand-spun wheel); a push or a brake changes ω by several rad/s within a
  second.  The baseline averages the 2ω ripple of an elliptical projection
  (unequal gains) away.

The window is the longest stretch where the wheel turns (radius above
``amplitude_fraction`` of its typical value, |ω| > ``min_rate_radps``) and
|ω̇| < ``max_spin_accel_radps2``, shrunk by ``margin_s`` at both ends so it
stays inside the true free spin.  The differences look ``lag_s`` ahead and
behind, so a push or brake taints ω̇ up to ~``lag_s`` into the spin: the
window loses ≈ ``lag_s`` + ``margin_s`` at each end (≈ 2 s of a 60–90 s spin).

Works at any sample rate and either spin direction.  The search looks only
below ``lowpass_hz``, so it runs on block means at about ``SEARCH_RATE_HZ``
(interpolated onto a grid at the median rate when that is slower): its time
and memory follow the sample count.  Gaps up to ``MAX_BRIDGED_GAP_S`` are
bridged; longer ones split the recording into stretches searched one by one
(the longest free spin wins), so no grid ever spans a gap — one timestamp a
day late would otherwise make it 17 million points long.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint import revolution_mean, rotating_phase
from wheelcal.recording import Recording, RecordingError


@dataclass(frozen=True)
class WindowSearch:
    """Settings of :func:`find_free_spin` (see the module docstring)."""

    highpass_hz: float = 0.15
    lowpass_hz: float = 8.0
    lag_s: float = 1.0
    max_spin_accel_radps2: float = 0.6
    min_rate_radps: float = 1.5
    amplitude_fraction: float = 0.5
    margin_s: float = 0.5
    min_duration_s: float = 5.0

    def __post_init__(self) -> None:
        if not (0 < self.highpass_hz < self.lowpass_hz):
            raise ValueError("need 0 < highpass_hz < lowpass_hz")
        for name in ("lag_s", "max_spin_accel_radps2", "min_duration_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")


@dataclass(frozen=True)
class FreeSpinWindow:
    """The free spin found in a recording (times in the recording's seconds)."""

    start_s: float
    end_s: float
    reason: str
    omega_start_radps: float
    omega_end_radps: float
    max_spin_accel_radps2: float

    @property
    def duration_s(self) -> float:
        """Length of the window."""
        return self.end_s - self.start_s


def _moving_average(x: np.ndarray, n: int) -> np.ndarray:
    if n <= 1:
        return x
    kernel = np.ones(n) / n
    return np.convolve(x, kernel, mode="same")


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start (inclusive) and stop (exclusive) indices of the True runs of ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


#: Gaps longer than this are not bridged: the search runs on each stretch between them.
MAX_BRIDGED_GAP_S = 1.0
#: A stretch whose regular grid would hold more than this × its samples is not searched.
MAX_GRID_PER_SAMPLE = 4.0


def contiguous_stretches(time_s: np.ndarray, rate_hz: float) -> list[slice]:
    """The runs of samples between gaps longer than ``MAX_BRIDGED_GAP_S`` (and 16 periods).

    A window search resamples to a regular grid; across a gap that grid would
    grow with the time span instead of the sample count (one stamp a day late:
    17 million points at 200 Hz).  Gaps this long cannot be bridged anyway.
    """
    limit = max(MAX_BRIDGED_GAP_S, 16.0 / rate_hz)
    cuts = np.flatnonzero(np.diff(time_s) > limit) + 1
    edges = [0, *cuts.tolist(), time_s.size]
    return [slice(a, b) for a, b in itertools.pairwise(edges)]


def find_free_spin(recording: Recording, search: WindowSearch | None = None) -> FreeSpinWindow:
    """Find the free-spin window of a recording automatically.

    Parameters
    ----------
    recording:
        The whole session, samples in m/s².
    search:
        Thresholds and filter settings.

    Returns
    -------
    FreeSpinWindow
        ``start_s``/``end_s`` in the recording's time, with a reason text.

    Raises
    ------
    RecordingError
        If no free spin of at least ``min_duration_s`` is found.
    """
    search = search or WindowSearch()
    stretches = contiguous_stretches(recording.time_s, recording.rate_hz)
    if len(stretches) == 1:
        return _find_in_stretch(recording, search)
    # A recording with long gaps: each stretch between them on its own, the longest spin wins.
    found, errors = [], []
    for part in stretches:
        if part.stop - part.start < 2:
            continue
        keep = np.zeros(recording.samples, dtype=bool)
        keep[part] = True
        piece = recording.select(keep)
        try:
            found.append(_find_in_stretch(piece, search))
        except RecordingError as exc:
            errors.append(str(exc))
    if not found:
        raise RecordingError(
            f"{recording.source}: no free spin found in any of the {len(stretches)} stretches "
            f"between gaps longer than {MAX_BRIDGED_GAP_S:g} s ({errors[0] if errors else ''})"
        )
    best = max(found, key=lambda w: w.duration_s)
    return dataclasses.replace(
        best,
        reason=best.reason + f" (in the longest of {len(stretches)} stretches between gaps "
        f"longer than {MAX_BRIDGED_GAP_S:g} s)",
    )


@dataclass(frozen=True, eq=False)
class _LowPass:
    """A zero-phase low-pass: its sections, their steady-state start and the padding."""

    sos: np.ndarray
    zi: np.ndarray  # sosfilt_zi(sos): the state of a unit step
    edge: int  # samples of odd extension at each end (sosfiltfilt's default)

    def filtfilt(self, rows: np.ndarray) -> np.ndarray:
        """``scipy.signal.sosfiltfilt(sos, rows, axis=-1)``, the same numbers.

        Done here so the filter's start state is solved once per design, not per call.
        """
        from scipy import signal

        edge = self.edge
        if rows.shape[1] <= edge:  # too short to pad: scipy's own message
            return signal.sosfiltfilt(self.sos, rows, axis=-1)
        ext = np.concatenate(
            [
                2 * rows[:, :1] - rows[:, edge:0:-1],
                rows,
                2 * rows[:, -1:] - rows[:, -2 : -(edge + 2) : -1],
            ],
            axis=1,
        )
        zi = self.zi[:, None, :]  # (sections, 1, 2): one state per row
        y, _ = signal.sosfilt(self.sos, ext, axis=-1, zi=zi * ext[:, :1])
        y = y[:, ::-1]
        y, _ = signal.sosfilt(self.sos, y, axis=-1, zi=zi * y[:, :1])
        return y[:, ::-1][:, edge:-edge]


@functools.lru_cache(maxsize=16)
def _lowpass(cutoff_hz: float, rate_hz: float) -> _LowPass:
    """2nd-order Butterworth low-pass as second-order sections (designed once per rate)."""
    from scipy import signal

    sos = signal.butter(2, cutoff_hz, fs=rate_hz, output="sos")
    zi = signal.sosfilt_zi(sos)
    # sosfiltfilt's default padding: 3 × taps, less the sections' zeros at the origin.
    taps = 2 * sos.shape[0] + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    zi.setflags(write=False)
    return _LowPass(sos, zi, 3 * taps)


#: The search runs on block means at about this rate (it only looks below ``lowpass_hz``).
SEARCH_RATE_HZ = 50.0


def _search_grid(recording: Recording, rate: float, n: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Regular times, samples on them as rows (3, n), and their rate, for the window search.

    Faster than 2 × ``SEARCH_RATE_HZ``, the samples are averaged in blocks of
    m = ⌊rate / SEARCH_RATE_HZ⌋ sample periods: a boxcar whose response at
    the search's 8 Hz low-pass is ≥ 0.96, without ever building the full-rate
    grid (time and memory then scale with the samples, at any rate).  Blocks a
    gap left empty are interpolated.  Slower, the samples are interpolated onto
    the grid at their median rate.
    """
    t, accel = recording.time_s, recording.accel_mps2
    t0 = float(t[0])
    m = int(rate // SEARCH_RATE_HZ)
    if m < 2:
        grid = t0 + np.arange(n) / rate
        return grid, np.vstack([np.interp(grid, t, accel[:, k]) for k in range(3)]), rate
    block_rate = rate / m
    bins = ((t - t0) * block_rate).astype(np.int64)
    count = np.bincount(bins)
    centre = t0 + (np.arange(count.size) + 0.5) / block_rate
    filled = count > 0
    v = np.empty((3, count.size))
    for k in range(3):
        mean = np.bincount(bins, weights=accel[:, k], minlength=count.size)[filled] / count[filled]
        v[k] = mean if filled.all() else np.interp(centre, centre[filled], mean)
    return centre, v, block_rate


def _find_in_stretch(recording: Recording, search: WindowSearch) -> FreeSpinWindow:
    """:func:`find_free_spin` on samples without long gaps (a regular grid bounded by them)."""
    rate = recording.rate_hz
    t0 = float(recording.time_s[0])
    n = int(np.floor(recording.duration_s * rate)) + 1
    if n > MAX_GRID_PER_SAMPLE * recording.samples + 64:
        raise RecordingError(
            f"{recording.source}: the samples are too sparse for their median rate "
            f"({recording.samples} samples over {recording.duration_s:.1f} s at "
            f"{rate:.4g} Hz): too many gaps to search for a free spin"
        )
    grid, v, rate = _search_grid(recording, rate, n)  # v: rows (3, n)
    n = grid.size
    lag = max(round(search.lag_s * rate / 2), 1)  # half the baseline, in samples
    if n < 8 * lag:
        raise RecordingError(
            f"{recording.source}: {recording.duration_s:.1f} s is too short to find a free spin"
        )

    omega, omega_dot, amplitude = _rate_and_amplitude(v, rate, lag, search)
    with np.errstate(invalid="ignore"):
        steady = (omega > search.min_rate_radps) & (
            np.abs(omega_dot) < search.max_spin_accel_radps2
        )
    # The rotating gravity component keeps its size g sin α through a free spin.
    typical = np.median(amplitude[steady]) if np.any(steady) else np.inf
    with np.errstate(divide="ignore", invalid="ignore"):  # an amplitude of 0: not free
        ratio = np.abs(np.log(amplitude / typical))
    free = steady & (ratio < np.log(1 / search.amplitude_fraction))
    starts, stops = _runs(free)
    if starts.size == 0:
        raise RecordingError(
            f"{recording.source}: no free spin found (no stretch where the wheel turns "
            f"faster than {search.min_rate_radps} rad/s with |dω/dt| < "
            f"{search.max_spin_accel_radps2} rad/s²)"
        )
    best = int(np.argmax(stops - starts))
    first, last = int(starts[best]), int(stops[best]) - 1
    # A run that reaches the first/last valid estimate may go on beyond the data.
    start_s = grid[first] + search.margin_s if first > 2 * lag else t0
    # (the grid's last point is a block's centre: the data go on to the last sample)
    end_s = grid[last] - search.margin_s if last < n - 1 - 2 * lag else float(recording.time_s[-1])
    if end_s - start_s < search.min_duration_s:
        raise RecordingError(
            f"{recording.source}: no free spin found: the longest stretch that looks like "
            f"one lasts {max(end_s - start_s, 0):.1f} s (need {search.min_duration_s:g} s)"
        )
    return _free_spin_window(recording, grid, omega, omega_dot, (start_s, end_s), lag)


def _rate_and_amplitude(
    v: np.ndarray, rate: float, lag: int, search: WindowSearch
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """|ω|, |ω̇| (NaN where the baseline 2·lag does not fit) and the rotating part's amplitude.

    ``v``: the samples on the search grid, as rows (3, n).
    """
    n = v.shape[1]
    # Noise: zero-phase low-pass (SOS: stable at any rate).
    v = _lowpass(min(search.lowpass_hz, 0.4 * rate), rate).filtfilt(v)
    # A rough phase from dv/dt: differentiation suppresses the slow part
    # (o, r ω², g cos α …) without the seconds-long ringing a high-pass filter
    # shows after the push's step in r ω².  It only sets the revolution windows.
    rough, _ = rotating_phase(np.gradient(v, axis=1) * rate)
    ramp = np.maximum.accumulate(rough)
    max_half = int(np.pi / search.min_rate_radps * rate)
    # The rotating part: v minus its mean over one revolution (cancels the
    # rotation exactly, keeps the slow part out), and its phase.
    phase, radius = rotating_phase(v - revolution_mean(v, ramp, max_half))
    amplitude = _moving_average(radius, 2 * lag)

    # |ω| and |ω̇| from phase differences over the baseline 2·lag.
    omega = np.full(n, np.nan)
    omega[lag:-lag] = (phase[2 * lag :] - phase[: -2 * lag]) / (2 * lag / rate)
    omega_dot = np.full(n, np.nan)
    omega_dot[2 * lag : -2 * lag] = (omega[3 * lag : -lag] - omega[lag : -3 * lag]) / (
        2 * lag / rate
    )
    return omega, omega_dot, amplitude


def _side(recording: Recording, edge_s: float, what: str, before: bool) -> str:
    """``what`` left out beside the window, and "clipped spin" when samples clipped there."""
    times = recording.clipped_time_s
    if times is None or not np.any(times < edge_s if before else times > edge_s):
        return what
    return f"{what}, and spin whose samples clipped"


def clipped_words(recording: Recording, start_s: float, end_s: float) -> str:
    """What the window's words must add when the reader dropped clipped samples.

    "Left out 27.9 s before (rest, push)" is not the whole truth when part of those
    27.9 s was spin whose samples clipped at a rail and were dropped: say how many,
    where, and that the spin there was too fast for the sensor's range.
    """
    times = recording.clipped_time_s
    if times is None or times.size == 0:
        return ""
    parts = []
    for label, inside in (
        ("before the window", times < start_s),
        ("inside it", (times >= start_s) & (times <= end_s)),
        ("after it", times > end_s),
    ):
        if inside.any():
            t = times[inside]
            parts.append(f"{inside.sum()} in {t.min():.1f}–{t.max():.1f} s {label}")
    return (
        f"; {times.size} samples clipped at a rail were dropped ({', '.join(parts)}): the "
        "spin there was too fast for the sensor's range"
    )


def _free_spin_window(
    recording: Recording,
    grid: np.ndarray,
    omega: np.ndarray,
    omega_dot: np.ndarray,
    span_s: tuple[float, float],
    lag: int,
) -> FreeSpinWindow:
    """The window ``span_s`` (recording times) with its rates and the reason it was chosen."""
    start_s, end_s = span_s
    inside = (grid >= start_s) & (grid <= end_s)
    w = omega[inside]
    w_start = float(np.nanmedian(w[: 4 * lag]))
    w_end = float(np.nanmedian(w[-4 * lag :]))
    max_acc = float(np.nanmax(np.abs(omega_dot[inside])))
    before = start_s - float(recording.time_s[0])
    after = float(recording.time_s[-1]) - end_s
    reason = (
        f"free spin {start_s:.2f}–{end_s:.2f} s ({end_s - start_s:.1f} s): "
        f"|ω| {w_start:.2f} → {w_end:.2f} rad/s, |dω/dt| ≤ {max_acc:.2f} rad/s² inside; "
        f"left out {before:.1f} s before ({_side(recording, start_s, 'rest, push', True)}) and "
        f"{after:.1f} s after ({_side(recording, end_s, 'brake, rest', False)})"
        + clipped_words(recording, start_s, end_s)
    )
    return FreeSpinWindow(
        start_s=float(start_s),
        end_s=float(end_s),
        reason=reason,
        omega_start_radps=w_start,
        omega_end_radps=w_end,
        max_spin_accel_radps2=max_acc,
    )


@dataclass(frozen=True)
class MotionSearch:
    """Settings of :func:`find_motion_window` (a window for gyro-aided fits)."""

    min_rate_radps: float = 1.5
    max_spin_accel_radps2: float = 8.0
    smooth_s: float = 0.25
    margin_s: float = 0.5
    min_duration_s: float = 5.0


def _smoothed_gyro_rate(recording: Recording, search: MotionSearch) -> np.ndarray:
    """|ω| from the gyroscope at every sample (gaps interpolated), moving-averaged."""
    gyro = getattr(recording, "gyro_radps", None)
    if gyro is None:
        raise RecordingError(f"{recording.source}: no gyroscope to find the wheel's motion")
    t = recording.time_s
    valid = np.all(np.isfinite(gyro), axis=1)
    rate = np.interp(t, t[valid], np.linalg.norm(gyro[valid], axis=1))
    return _moving_average(rate, max(1, round(search.smooth_s * recording.rate_hz)))


def find_motion_window(recording: Recording, search: MotionSearch | None = None) -> FreeSpinWindow:
    """The whole motion the gyroscope measures: first to last stretch where the wheel turns.

    With a gyro the motion no longer has to be a free spin: the spline of the
    wheel angle follows a motor's steps, a second push or a brake, so every
    stretch where |ω| > ``min_rate_radps`` and the rate changes slower than
    ``max_spin_accel_radps2`` counts, and the window runs from the first to the
    last of them, the pushes and stops between included (a hand's shake there is
    what the disturbance check of the fit cuts).  Only its ends are cut where a
    hand starts or brakes the wheel faster than that (forces not in the model),
    shrunk by ``margin_s``.  A window never spans a gap of the stamps longer than
    ``MAX_BRIDGED_GAP_S``: between such gaps, the stretch that turns longest.
    """
    search = search or MotionSearch()
    t = recording.time_s
    rate = _smoothed_gyro_rate(recording, search)
    accel = np.gradient(rate, t)
    turning = (rate > search.min_rate_radps) & (np.abs(accel) < search.max_spin_accel_radps2)
    pieces = contiguous_stretches(t, recording.rate_hz)
    for part in pieces[1:]:
        turning[part.start] = False  # a run never spans a long gap
    starts, stops = _runs(turning)
    if starts.size == 0:
        raise RecordingError(
            f"{recording.source}: the gyroscope shows no stretch where the wheel turns faster "
            f"than {search.min_rate_radps} rad/s"
        )
    # The runs of the stretch (between long gaps) that turns longest.
    piece = np.searchsorted([p.start for p in pieces], starts, side="right") - 1
    turned = np.bincount(piece, weights=stops - starts, minlength=len(pieces))
    best = piece == int(np.argmax(turned))
    starts, stops = starts[best], stops[best]
    first, last = int(starts[0]), int(stops[-1]) - 1
    start_s = t[first] + (search.margin_s if first > 0 else 0.0)
    end_s = t[last] - (search.margin_s if last < t.size - 1 else 0.0)
    if end_s - start_s < search.min_duration_s:
        raise RecordingError(
            f"{recording.source}: the wheel turns for {max(end_s - start_s, 0):.1f} s at most "
            f"(need {search.min_duration_s:g} s)"
        )
    window = _gyro_window(t, rate, accel, start_s, end_s, reason="")
    joined = ""
    if starts.size > 1:
        between = float(np.sum(t[starts[1:]] - t[stops[:-1] - 1]))
        joined = (
            f"; {starts.size} stretches where the wheel turns, joined across "
            f"{starts.size - 1} push(es) or stop(s) ({between:.1f} s faster than "
            f"{search.max_spin_accel_radps2:g} rad/s² or slower than {search.min_rate_radps:g} "
            "rad/s)"
        )
    reason = (
        f"motion {start_s:.2f}–{end_s:.2f} s ({end_s - start_s:.1f} s) from the gyroscope: "
        f"|ω| {window.omega_start_radps:.2f} → {window.omega_end_radps:.2f} rad/s, speed "
        f"changes up to {window.max_spin_accel_radps2:.2f} rad/s² followed by the "
        "wheel-angle spline" + joined + clipped_words(recording, start_s, end_s)
    )
    return dataclasses.replace(window, reason=reason)


def fitted_stretches(time_s: np.ndarray, rate_hz: float) -> list[tuple[float, float]]:
    """The stretches of samples a fit used: runs between holes longer than 4 sample periods."""
    t = np.asarray(time_s, dtype=float)
    if t.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(t) > 4.0 / rate_hz) + 1
    edges = [0, *cuts.tolist(), t.size]
    return [(float(t[a]), float(t[b - 1])) for a, b in itertools.pairwise(edges) if b > a]


def _gyro_window(
    t: np.ndarray, rate: np.ndarray, accel: np.ndarray, start_s: float, end_s: float, reason: str
) -> FreeSpinWindow:
    """The window [start_s, end_s] with the gyro's rate at its ends and its fastest ω̇."""
    inside = (t >= start_s) & (t <= end_s)
    return FreeSpinWindow(
        start_s=float(start_s),
        end_s=float(end_s),
        reason=reason,
        omega_start_radps=float(rate[inside][0]),
        omega_end_radps=float(rate[inside][-1]),
        max_spin_accel_radps2=float(np.max(np.abs(accel[inside]))),
    )


def find_drive_window(
    recording: Recording, search: MotionSearch | None = None, rest_s: float = 1.0
) -> FreeSpinWindow:
    """A rolling wheel's drive: from its first motion to its last, stops included.

    The rolling model holds the vehicle's accelerations, stops and turns, so
    nothing inside the drive is cut; ``rest_s`` of rest is kept on each side.
    """
    search = search or MotionSearch()
    t = recording.time_s
    rate = _smoothed_gyro_rate(recording, search)
    moving = np.flatnonzero(rate > search.min_rate_radps)
    stretches = angle_stretches(t, recording.gyro_radps)  # gaps in the stamps included
    holes = len(stretches) - 1
    bounds = (float(t[0]), float(t[-1]))
    if len(stretches) > 1 and moving.size:  # the drive: the stretch that moves most
        most = max(stretches, key=lambda p: np.sum((moving >= p.start) & (moving < p.stop)))
        moving = moving[(moving >= most.start) & (moving < most.stop)]
        bounds = (float(t[most.start]), float(t[most.stop - 1]))
    if moving.size == 0:
        raise RecordingError(
            f"{recording.source}: the gyroscope shows no motion faster than "
            f"{search.min_rate_radps} rad/s"
        )
    start_s = max(bounds[0], float(t[moving[0]]) - rest_s)
    end_s = min(bounds[1], float(t[moving[-1]]) + rest_s)
    cut = (
        f"the rate is missing for more than {MAX_ANGLE_BRIDGE_S:g} s {holes} time(s) (gyro or "
        "accelerometer samples clipped, or a logger's gap), and the wheel angle, its "
        "integral, cannot be carried across"
        if holes
        else ""
    )
    if end_s - start_s < search.min_duration_s:
        raise RecordingError(
            f"{recording.source}: the wheel moves for {end_s - start_s:.1f} s "
            f"(need {search.min_duration_s:g} s)"
            + (f" in one piece: {cut} — use a wider gyro or accelerometer range" if cut else "")
        )
    reason = (
        f"drive {start_s:.2f}–{end_s:.2f} s ({end_s - start_s:.1f} s) from the gyroscope: "
        f"first to last motion with {rest_s:g} s of rest either side, stops included"
        + (f"; {cut}: the stretch that moves most between them" if cut else "")
    )
    return _gyro_window(t, rate, np.gradient(rate, t), start_s, end_s, reason)


#: The wheel angle, the gyro's integral, is not carried across a hole in the rate (gyro
#: rows left out or dropped: clipped, a logger's gap) longer than this (or than 2.5
#: sample periods, so that one missing row is always bridged): the wheel's speed peaks
#: inside a clipped stretch, and the rate drawn straight across it leaves ≈ ω̇ h²/4 in
#: the angle (0.006 rad at 10 rad/s²; an isolated glitch row is bridged).
MAX_ANGLE_BRIDGE_S = 0.05


def angle_stretches(time_s: np.ndarray, gyro_radps: np.ndarray) -> list[slice]:
    """The runs of samples between the rate's holes longer than ``MAX_ANGLE_BRIDGE_S``."""
    valid = np.flatnonzero(np.all(np.isfinite(gyro_radps), axis=1))
    if valid.size < 2:
        return [slice(0, time_s.size)]
    steps = np.diff(time_s[valid])
    limit = max(MAX_ANGLE_BRIDGE_S, 2.5 * float(np.median(np.diff(time_s))))
    cuts = np.flatnonzero(steps > limit)
    starts = [0, *(valid[cuts + 1]).tolist()]
    stops = [*(valid[cuts] + 1).tolist(), time_s.size]
    return [slice(a, b) for a, b in zip(starts, stops, strict=True)]
