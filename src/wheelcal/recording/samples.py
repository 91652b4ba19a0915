"""Checks and repairs of raw samples before they become a :class:`Recording`.

Real recordings have defects.  Each is either repaired — and the repair is
written into :attr:`Recording.notes`, so it reaches the report — or refused
with an error naming the file, when a repair would invent data:

==========================  ==================================  ===========================
defect                      repaired when                       refused when
==========================  ==================================  ===========================
NaN / inf samples           ≤ 1 % of samples: dropped           more
stray timestamps            short runs (≤ 64 samples) that      never (more than 1 % are
                            jump > 20 steps away and have no    left to the order check)
                            place among the others (a day
                            late, a flipped bit): ≤ 1 % dropped
samples out of order        ≤ 1 % backward steps, or any        many steps back by more than
                            number of steps back by ≤ 1 s       1 s (chaotic), or sorting
                            (writer threads), and sorting       interleaves two time ranges
                            restores a regular grid: sorted     (clock reset)
duplicate timestamps        ≤ 5 %: identical rows dropped,      more (stamps per packet,
                            differing rows averaged             not per sample)
gaps                        always kept (real timestamps),      never
                            reported
gross outliers              > 25 robust σ and > 1.5 g from      more than 1 %
                            the running median of 5, or
                            beyond 1000 g: ≤ 1 % dropped
clipped samples             ≤ 20 %: dropped                     more
too sparse                  —                                   < 10 samples per second
unit mislabel (g as m/s²)   never (ambiguous fixes are          at rest |a| ≈ 1 (or ≈ 96),
                            guesses)                            or median |a| ≪ g
too short                   —                                   < 10 s or < 100 samples
==========================  ==================================  ===========================

Clipping is found from ``full_scale_g`` when the session gives it (any axis
at ≥ 99.5 % of ±full scale), else as *runs at the extreme value*: a saturated
axis repeats its rail value — exactly, or toggling by a count or two — for
``clip_run_samples`` samples in a row, turn after turn, which noisy
unsaturated data never does at its maximum (only extremes beyond 1.5 g are
considered, so a quantised signal at rest is not flagged).

The unit check is scale-invariant: "quiet" stretches (per-axis spread below
2 % of |a|; a turning wheel spreads its axes by g sin α, far more) can only
be the sensor at rest, where |a| must be ≈ g.  A rest
level near 1 in data labelled m/s² means g; near 96 in data labelled g means
m/s².  Converting automatically would be a guess about a file that misstates
its own units, so the reader refuses and says how to state the unit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model import STANDARD_GRAVITY_MPS2
from wheelcal.recording.errors import SampleError


@dataclass(frozen=True)
class InputPolicy:
    """Thresholds for repairing versus refusing a recording (see the module table)."""

    max_nonfinite_fraction: float = 0.01
    max_backward_fraction: float = 0.01
    max_reorder_s: float = 1.0
    stray_stamp_steps: float = 20.0
    max_stray_run: int = 64
    max_stray_fraction: float = 0.01
    max_duplicate_fraction: float = 0.05
    gap_factor: float = 3.0
    max_clipped_fraction: float = 0.20
    #: … and with a gyroscope, whose integral is the wheel angle: a car's wheel clips the
    #: accelerometer whenever it drives fast (16 g at 0.15 m: 37 km/h), and the samples
    #: between are a whole calibration.  Clipped samples are left out either way.
    max_clipped_fraction_with_gyro: float = 0.80
    outlier_sigmas: float = 25.0
    outlier_floor_g: float = 1.5
    max_physical_g: float = 1000.0
    max_outlier_fraction: float = 0.01
    clip_run_samples: int = 3
    rail_jitter_counts: float = 2.0
    clip_margin: float = 0.995
    min_duration_s: float = 10.0
    min_rate_hz: float = 10.0
    min_samples: int = 100
    check_units: bool = True


@dataclass(frozen=True, eq=False)
class CleanSamples:
    """Samples after the checks: sorted unique stamps (int ns) and m/s² rows."""

    time_ns: np.ndarray
    accel_mps2: np.ndarray
    notes: tuple[str, ...]
    #: (3, 2) low/high rail per axis where clipping was found, NaN elsewhere.
    clip_limits_mps2: np.ndarray | None = None
    #: The clipped samples that were dropped: stamps (int ns) and rows (m/s²), for views.
    clipped_ns: np.ndarray | None = None
    clipped_mps2: np.ndarray | None = None


def percent(part: int, whole: int) -> str:
    """``part`` of ``whole`` in per cent, for notes (two significant digits)."""
    return f"{100.0 * part / max(whole, 1):.2g} %"


def clean_samples(
    path: str,
    time_ns: np.ndarray,
    accel_mps2: np.ndarray,
    *,
    unit: str,
    full_scale_g: float | None,
    policy: InputPolicy,
    unit_remedy: str | None = None,
    unit_stated_by: str = "the file",
) -> CleanSamples:
    """Repair what can be repaired, refuse the rest (see the module docstring).

    Parameters
    ----------
    path:
        The file (and topic), for messages.
    time_ns:
        Stamps, int64 ns, any order.
    accel_mps2:
        Samples (N, 3) already converted to m/s².
    unit:
        The unit the file claimed (``"m/s^2"`` or ``"g"``), for the unit check.
    full_scale_g:
        The sensor's range if known, for clipping.
    policy:
        Thresholds.
    unit_remedy:
        How to state the right unit for this file's format (for the unit
        check's message); ``None``: ``--accel-unit`` or the channel metadata.
    unit_stated_by:
        Who claimed ``unit``, as the unit check's message names it: ``"the
        file"``, or the option that overrode it (``"--accel-unit g"``).

    Raises
    ------
    SampleError
        With the file and the reason.
    """
    t = np.asarray(time_ns, dtype=np.int64)
    a = np.asarray(accel_mps2, dtype=float)
    notes: list[str] = []
    if t.size == 0:
        raise SampleError(path, "the accelerometer topic holds no samples")

    t, a = _drop_nonfinite(path, t, a, policy, notes)
    t, a = _drop_stray_stamps(t, a, policy, notes)
    t, a = _order(path, t, a, policy, notes)
    t, a = _merge_duplicates(path, t, a, policy, notes)
    t, a = _drop_leading_zeros(path, t, a, notes)
    step_ns = _typical_step_ns(t)  # sorted and unique from here on
    _report_gaps(t, step_ns, policy, notes)
    t, a = _drop_gross_outliers(path, t, a, policy, notes)
    t, a, rails, clipped = _drop_clipped(path, t, a, full_scale_g, policy, notes)
    _check_rate(path, t.size, step_ns, policy)
    _check_alive(path, a)
    if policy.check_units:
        _check_units(path, a, unit, unit_remedy, unit_stated_by)
    duration_s = (t[-1] - t[0]) * 1e-9 if t.size else 0.0
    if t.size < policy.min_samples or duration_s < policy.min_duration_s:
        raise SampleError(
            path,
            f"the recording is too short: {t.size} usable samples over {duration_s:.2f} s; "
            f"a calibration needs at least {policy.min_samples} samples and "
            f"{policy.min_duration_s:g} s of free spin",
        )
    clipped_ns, clipped_mps2 = clipped if clipped is not None else (None, None)
    return CleanSamples(t, a, tuple(notes), rails, clipped_ns, clipped_mps2)


def rows_all(mask: np.ndarray) -> np.ndarray:
    """``mask.all(axis=1)`` of an (N, k) boolean array, the same values, faster.

    numpy reduces an (N, 3) array along its rows in steps of three elements
    (~8 ns per element); the columns combined with ``&`` take a tenth of that.
    """
    return _combined_columns(mask, np.logical_and, np.all)


def rows_any(mask: np.ndarray) -> np.ndarray:
    """``mask.any(axis=1)`` of an (N, k) boolean array, as :func:`rows_all`."""
    return _combined_columns(mask, np.logical_or, np.any)


def _combined_columns(mask: np.ndarray, combine: np.ufunc, reduce) -> np.ndarray:
    """The columns of ``mask`` combined one after the other (``reduce(mask, axis=1)``)."""
    if mask.ndim != 2 or mask.shape[1] == 0:
        return reduce(mask, axis=1)
    out = mask[:, 0].copy()
    for k in range(1, mask.shape[1]):
        combine(out, mask[:, k], out=out)
    return out


def _drop_nonfinite(path, t, a, policy, notes):
    finite = np.isfinite(a)
    if finite.all():
        return t, a
    bad = ~rows_all(finite)
    count = int(bad.sum())
    if count > policy.max_nonfinite_fraction * t.size:
        raise SampleError(
            path,
            f"{count} of {t.size} samples ({percent(count, t.size)}) are NaN or infinite; "
            f"at most {policy.max_nonfinite_fraction:.0%} can be dropped",
        )
    notes.append(f"dropped {count} NaN/inf samples ({percent(count, t.size)})")
    return t[~bad], a[~bad]


def _drop_leading_zeros(path, t, a, notes):
    """Drop rows of exact zeros on all three axes at the start (a logger's first rows).

    A real accelerometer never reads exactly (0, 0, 0): gravity alone is 9.8 m/s².
    Loggers often write zero rows before the sensor's first reading.
    """
    if not a.shape[0] or np.any(a[0] != 0.0):  # the usual case, without a pass over every row
        return t, a
    zero = np.all(a == 0.0, axis=1)
    if np.all(zero):
        return t, a  # nothing left: _check_alive names it
    first = int(np.argmin(zero))
    notes.append(
        f"dropped the first {first} samples: every axis reads exactly 0 (a logger's rows "
        "before the sensor's first reading)"
    )
    return t[first:], a[first:]


def _check_alive(path, a: np.ndarray) -> None:
    """Refuse a recording whose axes never change: the sensor was not read."""
    if a.shape[0] < 2:
        return
    flat = [k for k in range(3) if np.all(a[:, k] == a[0, k])]
    if not flat:
        return
    if len(flat) == 3 and np.all(a[0] == 0.0):
        raise SampleError(
            path,
            "every sample reads exactly 0 on all three axes: the sensor was not read (a "
            "logger writing zeros, a wrong register or topic)",
        )
    axes = ", ".join(f"{'xyz'[k]} = {a[0, k]:g} m/s²" for k in flat)
    raise SampleError(
        path,
        f"axis {axes} never changes over {a.shape[0]} samples: a dead or unread axis (a "
        "real axis reads noise and gravity); check the wiring, the register map or the topic",
    )


def _typical_step_ns(t: np.ndarray) -> float:
    """The median positive step between stamps (0 if there is none).

    From at most ~100k steps, evenly spread (a long recording's full diff
    would be a temporary of 8 B per sample for the same median).
    """
    if t.size > 200_000:
        at = np.arange(0, t.size - 1, (t.size - 1) // 100_000)
        d = t[at + 1] - t[at]
    else:
        d = np.diff(t)
    d = d[d > 0]
    return float(np.median(d)) if d.size else 0.0


def _drop_stray_stamps(t, a, policy, notes):
    """Drop short runs of samples whose stamps are far from where they sit (corrupt stamps).

    A run of at most ``max_stray_run`` samples bounded by jumps of more than
    ``stray_stamp_steps`` sampling steps is *stray* when its stamps have no
    place among the others: sorting would put them among other samples (no
    hole of their size there), or beyond the recording's ends (a stamp a day
    late, a flipped bit of ``sec``).  Samples that fill a hole are merely out
    of order and left to :func:`_order`.  A run at the file's start or end is
    stray only when it lies farther from the rest than the rest's own span
    (a recording may start or end after a real gap).  At most
    ``max_stray_fraction`` of the samples are dropped; more is no outlier.
    """
    if t.size < 3:
        return t, a
    dt = _typical_step_ns(t)
    if dt <= 0:
        return t, a
    d = np.diff(t)
    far = policy.stray_stamp_steps * dt
    jumps = np.flatnonzero((d > far) | (d < -far))
    allowed = int(policy.max_stray_fraction * t.size)
    if jumps.size == 0 or jumps.size > 2 * allowed + 2:
        return t, a
    # Candidate runs [start, stop): between two jumps, or from an end to a jump.
    bounds = np.concatenate([[-1], jumps, [t.size - 1]])
    starts, stops = bounds[:-1] + 1, bounds[1:] + 1
    short = (stops - starts) <= policy.max_stray_run
    short &= (stops - starts) < t.size // 2
    if not np.any(short):
        return t, a
    ordered = np.sort(t)
    stray = np.zeros(t.size, bool)
    for start, stop in zip(starts[short].tolist(), stops[short].tolist(), strict=True):
        run = t[start:stop]
        lo, hi = int(run.min()), int(run.max())
        inside = int(np.searchsorted(ordered, hi, "right") - np.searchsorted(ordered, lo, "left"))
        below = np.searchsorted(ordered, lo, "left") - 1
        above = np.searchsorted(ordered, hi, "right")
        edge = start == 0 or stop == t.size
        if inside > run.size:  # sorting would interleave them with other samples
            is_stray = True
        elif below < 0 or above >= ordered.size:  # beyond an end of the other samples
            if below < 0:
                distance, rest_span = int(ordered[above]) - hi, int(ordered[-1] - ordered[above])
            else:
                distance, rest_span = lo - int(ordered[below]), int(ordered[below] - ordered[0])
            is_stray = distance > (max(far, rest_span) if edge else far)
        else:  # among the others: stray unless they fill a hole of their size
            hole = int(ordered[above]) - int(ordered[below])
            is_stray = hole < (run.size + 0.5) * dt
        if is_stray:
            stray[start:stop] = True
    count = int(stray.sum())
    if count == 0 or count > allowed:
        return t, a
    where = ", ".join(f"sample {int(i)}" for i in np.flatnonzero(stray)[:3])
    more = ", …" if count > 3 else ""
    notes.append(
        f"dropped {count} sample(s) with stray timestamps far from their neighbours "
        f"({where}{more}; a corrupt or late stamp)"
    )
    return t[~stray], a[~stray]


def _short_steps(t: np.ndarray, dt_ns: float) -> int:
    """Forward steps (zero included) shorter than half the typical interval."""
    d = np.diff(t)
    return int(np.count_nonzero((d >= 0) & (d < 0.5 * dt_ns)))


def _order(path, t, a, policy, notes):
    """Sort stamps that are locally out of order (several writer threads); refuse chaos.

    MCAP does not require log-time order.  Sorting is safe when every
    backward step is short (at most ``max_reorder_s``) — or when there are
    few (``max_backward_fraction``) — and the sorted stamps are as regular as
    the file's own (sorting creates no interleaving of two time ranges).
    """
    d = np.diff(t)
    backward = int(np.count_nonzero(d < 0))
    if backward == 0:
        return t, a
    worst = int(np.argmin(d))
    local = -int(d[worst]) <= policy.max_reorder_s * 1e9
    if backward > policy.max_backward_fraction * t.size and not local:
        raise SampleError(
            path,
            f"timestamps go backwards {backward} times in {t.size} samples (by up to "
            f"{-d[worst] * 1e-9:.3g} s): the order of the samples is chaotic and cannot "
            "be repaired",
        )
    order = np.argsort(t, kind="stable")
    sorted_t = t[order]
    dt_ns = _typical_step_ns(sorted_t)
    created = _short_steps(sorted_t, dt_ns) - _short_steps(t, dt_ns)
    if created > 2:
        raise SampleError(
            path,
            f"timestamps jump back by {-d[worst] * 1e-9:.3f} s at sample {worst + 1}, and "
            "sorting would interleave two stretches of time (a clock reset?); "
            "refusing to guess the order",
        )
    notes.append(f"sorted {backward} out-of-order timestamp steps into time order")
    return sorted_t, a[order]


def _merge_duplicates(path, t, a, policy, notes):
    same = np.diff(t) == 0
    count = int(same.sum())
    if count == 0:
        return t, a
    if count > policy.max_duplicate_fraction * t.size:
        raise SampleError(
            path,
            f"{count} of {t.size} samples ({percent(count, t.size)}) repeat the previous "
            "timestamp: the device seems to stamp whole packets, but every sample needs "
            "its own time",
        )
    # t is sorted, so equal stamps are contiguous groups starting at ``first``.
    unique_t, first, sizes = np.unique(t, return_index=True, return_counts=True)
    spread = np.maximum.reduceat(a, first, axis=0) - np.minimum.reduceat(a, first, axis=0)
    differing = np.any(spread > 0, axis=1)
    out = a[first].copy()  # identical copies: keep the first, bit for bit
    if np.any(differing):
        sums = np.add.reduceat(a, first, axis=0)
        out[differing] = sums[differing] / sizes[differing, None]
    multi = sizes > 1
    dropped = int(np.sum(sizes[multi & ~differing] - 1))
    averaged = int(np.sum(multi & differing))
    parts = []
    if dropped:
        parts.append(f"{dropped} identical copies dropped")
    if averaged:
        parts.append(f"{averaged} stamps with differing values averaged")
    notes.append(f"{count} samples repeated a timestamp: " + ", ".join(parts))
    return unique_t, out


_BLOCK_ROWS = 1 << 14  # rows per piece of the running median (bounded temporaries)


def _median5(p: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray, e: np.ndarray):
    """Element-wise median of five arrays with nine min/max operations (no sorting).

    Of the four values p, q, r, s the smallest and the largest lie on either
    side of the five's median, so dropping them leaves it: the median of the
    middle two of the four and ``e``.
    """
    low = np.maximum(np.minimum(p, q), np.minimum(r, s))  # middle two of p, q, r, s
    high = np.minimum(np.maximum(p, q), np.maximum(r, s))
    return np.maximum(np.minimum(low, high), np.minimum(np.maximum(low, high), e))


def _median5_residual(a: np.ndarray, start: int, stop: int) -> np.ndarray:
    """``a[start:stop]`` minus the running median of 5 (per axis; the ends reflected)."""
    lo, hi = max(start - 2, 0), min(stop + 2, a.shape[0])
    x = a[lo:hi]
    pad = (2 - (start - lo), 2 - (hi - stop))
    if pad != (0, 0):
        x = np.pad(x, (pad, (0, 0)), mode="reflect" if x.shape[0] > 2 else "edge")
    m = x.shape[0] - 4
    median = _median5(x[0:m], x[1 : m + 1], x[3 : m + 3], x[4 : m + 4], x[2 : m + 2])
    return a[start:stop] - median


def _drop_gross_outliers(path, t, a, policy, notes):
    """Drop single samples (or pairs) far from their neighbours: bit errors, glitches.

    A sample is a gross outlier when it differs from the running median of
    five (its own and two neighbours each side) by more than
    ``outlier_sigmas`` robust σ of that difference (1.4826 × its median
    absolute value, per axis) *and* by more than ``outlier_floor_g`` g — so
    the signal itself never is one: a wheel's fastest change, gravity turning
    once per revolution, moves a sample at most ~1 g from that median at
    8 samples per turn; the centripetal part changes slowly; a clipped rail is
    flat; vibration is noise, which robust σ measures.  Values beyond
    ``max_physical_g`` (no accelerometer reads 1000 g) are outliers whatever
    their neighbours.  More than ``max_outlier_fraction`` is refused.
    """
    n = t.size
    if n < 5:
        return t, a
    g = STANDARD_GRAVITY_MPS2
    floor = policy.outlier_floor_g * g
    wild_limit = policy.max_physical_g * g
    if _steps_too_small_for_outliers(a, floor, wild_limit):
        return t, a
    with np.errstate(all="ignore"):
        # One pass for candidates beyond the floor (good data has none: done) ...
        rows, residuals = [], []
        for start in range(0, n, _BLOCK_ROWS):
            stop = min(start + _BLOCK_ROWS, n)
            r = np.abs(_median5_residual(a, start, stop))
            piece = a[start:stop]
            if piece.max() > wild_limit or piece.min() < -wild_limit:
                r[np.any(np.abs(piece) > wild_limit, axis=1)] = np.inf
            beyond = r > floor
            if beyond.any():  # good data: never
                hit = np.flatnonzero(rows_any(beyond))
                rows.append(hit + start)
                residuals.append(r[hit])
        if not rows:
            return t, a
        # ... then the noise scale, from ~20k rows (evenly spread): ample for a median.
        probe_rows = np.arange(0, n, max(1, n // 20_000))
        near = a[np.clip(probe_rows[:, None] + np.arange(-2, 3), 0, n - 1)]  # (m, 5, 3)
        centre = _median5(near[:, 0], near[:, 1], near[:, 3], near[:, 4], near[:, 2])
        sigma = 1.4826 * np.median(np.abs(a[probe_rows] - centre), axis=0)
        limit = np.maximum(policy.outlier_sigmas * sigma, floor)
        rows, residuals = np.concatenate(rows), np.concatenate(residuals)
        bad = np.zeros(n, bool)
        bad[rows[np.any(residuals > limit, axis=1)]] = True
    count = int(bad.sum())
    if count == 0:
        return t, a
    if count > policy.max_outlier_fraction * n:
        raise SampleError(
            path,
            f"{count} of {n} samples ({percent(count, n)}) jump far from their neighbours "
            f"(more than {policy.outlier_floor_g:g} g and {policy.outlier_sigmas:g} robust σ "
            "from the running median): the data are too damaged to clean",
        )
    flagged = np.flatnonzero(bad)
    worst = int(flagged[np.argmax(np.max(np.abs(a[flagged]), axis=1))])
    notes.append(
        f"dropped {count} gross outlier sample(s) ({percent(count, n)}) far from their "
        f"neighbours (largest |a| = {np.max(np.abs(a[worst])):.3g} m/s² at "
        f"t = {(t[worst] - t[0]) * 1e-9:.3f} s)"
    )
    return t[~bad], a[~bad]


def _steps_too_small_for_outliers(a: np.ndarray, floor: float, wild_limit: float) -> bool:
    """True when no sample can lie ``floor`` from its running median of five: none is one.

    At least three of the five lie at or below their median and three at or
    above it; a sample and its two neighbours lie within one step of the
    sample (the largest step between neighbours, ends reflected alike), so
    the median does too.  When that step is below the floor (with a margin
    for rounding) and no value is beyond ``wild_limit``, the full search (a
    dozen passes over the samples) would find nothing.
    """
    if not (a.max() <= wild_limit and a.min() >= -wild_limit):
        return False
    steps = np.diff(a, axis=0)
    np.abs(steps, out=steps)
    return bool(steps.max() < floor * (1.0 - 1e-9))


def _report_gaps(t, dt_ns, policy, notes):
    d = np.diff(t)
    if d.size == 0:
        return
    gaps = np.flatnonzero(d > policy.gap_factor * dt_ns)
    if gaps.size == 0:
        return
    longest = int(gaps[np.argmax(d[gaps])])
    missing = float(np.sum(d[gaps] - dt_ns)) * 1e-9
    notes.append(
        f"{gaps.size} gap(s) in the samples (longest {d[longest] * 1e-9:.3f} s at "
        f"t = {(t[longest] - t[0]) * 1e-9:.3f} s, {missing:.3f} s missing in total); "
        "real timestamps kept"
    )


def _drop_clipped(path, t, a, full_scale_g, policy, notes):
    """Drop clipped samples; also return the rails (3, 2: low, high; NaN = none found).

    And the dropped samples themselves (stamps, rows), for a view to mark.

    The rails travel with the recording: dropping only the samples *at* a rail
    keeps their neighbours whose noise happened to stay below it, a selection
    that biases the peaks low; the estimator therefore also leaves out the
    stretches the model predicts near a rail (session/fit.py).
    """
    limits = np.full((3, 2), np.nan)
    if full_scale_g is not None:
        limit = policy.clip_margin * full_scale_g * STANDARD_GRAVITY_MPS2
        clipped = rows_any(np.abs(a) >= limit)
        how = f"at the sensor range ±{full_scale_g:g} g"
        limits[:] = [-limit, limit]
    else:
        clipped = np.zeros(t.size, dtype=bool)
        rails = []
        # Per axis, contiguous (numpy's reductions along an (N, 3) array's rows are slow).
        axes = np.ascontiguousarray(a.T)
        extremes = np.stack([axes.min(axis=1), axes.max(axis=1)], axis=1)  # (3 axes, min/max)
        for k, side in np.argwhere(np.abs(extremes) >= 1.5 * STANDARD_GRAVITY_MPS2):
            value = float(extremes[k, side])
            at = _at_rail(axes[k], value, policy)
            if at is not None:
                clipped |= at
                limits[k, side] = value
                rails.append(f"{'xyz'[k]} = {value:+.4g}")
        how = "at the rails " + ", ".join(rails) + " m/s² (runs at the extreme value)"
    count = int(clipped.sum())
    if count == 0:
        return t, a, None, None
    if count > policy.max_clipped_fraction * t.size:
        raise SampleError(
            path,
            f"{count} of {t.size} samples ({percent(count, t.size)}) are clipped {how}: "
            "the sensor range is too small for this spin (use a larger range or spin slower)",
        )
    notes.append(f"dropped {count} clipped samples ({percent(count, t.size)}) {how}")
    return t[~clipped], a[~clipped], limits, (t[clipped], a[clipped])


def run_lengths(mask: np.ndarray) -> np.ndarray:
    """The lengths of the runs of True in ``mask``, in order."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)


def _at_rail(axis: np.ndarray, value: float, policy: InputPolicy) -> np.ndarray | None:
    """Samples of one axis sitting at its rail ``value`` (None when it is no rail).

    A saturated ADC repeats its rail value — or toggles by a count or two
    around it.  The rail band is ``rail_jitter_counts`` counts wide (one count
    = the data's smallest step near the rail); an axis is at a rail when runs
    of ``clip_run_samples`` samples sit in that band, repeatedly (a wheel
    saturates once per turn; noise reaches its maximum once).
    """
    margin = 0.05 * abs(value)
    near = np.unique(axis[(axis >= value - margin) & (axis <= value + margin)])
    steps = np.diff(near)
    count = float(steps[steps > 0].min()) if np.any(steps > 0) else 0.0
    band = policy.rail_jitter_counts * count + 1e-12 * abs(value)
    at = (axis >= value - band) & (axis <= value + band)  # |axis − value| ≤ band, no temporary
    runs = run_lengths(at)
    long_runs = runs[runs >= policy.clip_run_samples]
    exact = axis == value
    exact_runs = run_lengths(exact)
    if np.any(exact_runs >= policy.clip_run_samples):
        return at  # the rail repeats exactly (the original signature)
    if long_runs.size >= 2:
        return at
    return None


def rest_level(accel: np.ndarray, block: int = 50) -> float | None:
    """Median |a| over quiet blocks (per-axis spread < 2 % of |a|), or None if none.

    Only a sensor at rest is that quiet; the test does not depend on the unit.
    """
    n = accel.shape[0] // block
    if n == 0:
        return None
    per_piece = max(1, _BLOCK_ROWS // block)  # blocks per piece: bounded temporaries
    level = np.empty(n)
    spread = np.empty(n)
    for first in range(0, n, per_piece):
        last = min(first + per_piece, n)
        blocks = accel[first * block : last * block].reshape(last - first, block, 3)
        mean, std = _block_mean_std(blocks)
        level[first:last] = np.linalg.norm(mean, axis=1)
        spread[first:last] = std.max(axis=1)
    quiet = (level > 0) & (spread < 0.02 * level)
    if quiet.sum() < 2:
        return None
    return float(np.median(level[quiet]))


def _block_mean_std(blocks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``blocks.mean(axis=1)`` and ``blocks.std(axis=1)`` of (m, block, 3), bit for bit.

    numpy sums along axis 1 one block row after the other (no pairwise
    summation across it) — as it does along axis 0 of the contiguous
    (block, m, 3) copy, which is several times faster; the steps are those of
    ``numpy.std``: mean, deviations, their squares' mean, square root.
    """
    n = blocks.shape[1]
    rows = np.ascontiguousarray(blocks.transpose(1, 0, 2))
    mean = np.add.reduce(rows, axis=0) / n
    deviation = np.subtract(rows, mean, out=rows)
    np.multiply(deviation, deviation, out=deviation)
    return mean, np.sqrt(np.add.reduce(deviation, axis=0) / n)


def _check_rate(path, samples, step_ns, policy):
    """Refuse samples too sparse for a spinning wheel (e.g. one per second), before any fit."""
    if samples < 2:
        return
    dt_s = step_ns * 1e-9
    if dt_s > 0 and 1.0 / dt_s < policy.min_rate_hz:
        raise SampleError(
            path,
            f"the samples are {dt_s:.3g} s apart ({1.0 / dt_s:.3g} Hz): a wheel turning once "
            f"a second would get fewer than {policy.min_rate_hz * 1.0:g} samples per turn; "
            f"a calibration needs at least {policy.min_rate_hz:g} samples per second "
            "(record the sensor at its output rate, typically 100–1000 Hz)",
        )


def _check_units(path, a, unit, remedy=None, stated_by="the file"):
    g = STANDARD_GRAVITY_MPS2
    rest = rest_level(a)
    other = "m/s^2" if unit == "g" else "g"
    fix = remedy or (
        f"state the unit: --accel-unit {other} on the command line, or the channel's "
        "metadata unit ('g' or 'm/s^2') in the file"
    )
    if rest is not None:
        ratio = rest / g
        if unit == "m/s^2" and 0.06 < ratio < 0.16:
            raise SampleError(
                path,
                f"at rest the samples read |a| = {rest:.3g}, about 1: they look like g, "
                f"but {stated_by} says m/s^2 (at rest |a| would be ≈ {g:.2f}); {fix}",
            )
        if unit == "g" and 6.0 < ratio < 16.0:
            raise SampleError(
                path,
                f"at rest the samples read |a| = {rest / g:.3g} g: they look like m/s^2, "
                f"but {stated_by} says g; {fix}",
            )
        return
    median = float(np.sqrt(np.median(np.einsum("ij,ij->i", a, a))))
    if unit == "m/s^2" and 0.06 < median / g < 0.35:
        raise SampleError(
            path,
            f"the median |a| is {median:.3g} m/s^2, far below gravity ({g:.2f}); no sensor "
            f"on a wheel reads that little: the samples look like g labelled m/s^2; {fix}",
        )
