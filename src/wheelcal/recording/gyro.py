"""The gyroscope channel: kept aligned with the accelerometer, checked, clipped samples left out.

The gyro rides on the accelerometer's samples (one ROS 2 ``Imu`` message, or
one ``wheelcal.AccelBatch`` row, holds both), so it must go through the same
repairs — sorting, merged duplicate stamps, dropped NaN or clipped
accelerometer rows — without :func:`~wheelcal.recording.samples.clean_samples`
having to know about it.  :func:`align_to_samples` does that by *stamp*:
every stamp the accelerometer checks keep was a stamp of the raw data, so the
gyro row of each kept stamp is looked up (the mean of its rows when the stamp
was repeated, as the accelerometer's differing duplicates are averaged).

:func:`check_gyro` then judges the aligned rows.  Nothing here refuses a
recording for a gyro defect the accelerometer can live without; a defect is
left out and written into ``Recording.notes``:

=================================  ==============================================
what                               what happens
=================================  ==============================================
rows NaN, inf, or absent from      the row is NaN (left out); counted in a note
their message
isolated gross outliers (a         the row is NaN (left out); noted — one bad
logger's bit error: one sample     sample never costs a recording
far from its neighbours)
a channel of exact zeros           no gyro (many accelerometer-only drivers
                                   publish zeros); noted
no usable row at all               no gyro; noted
clipped rows                       NaN (left out), noted with the rail; never a
                                   refusal — the unclipped part still counts
readings beyond any MEMS gyro      **refused** (a unit stated wrongly is an
(> 4000 °/s), or beyond the        error, as for the accelerometer): the message
stated ``gyro_full_scale_dps``     says which unit the data look like
=================================  ==============================================

Clipping is found from ``gyro_full_scale_dps`` when the session states it (a
row with any axis at ≥ 99.5 % of the range), else as *runs at the extreme
value*: a saturated axis sits at its rail, which an unsaturated signal never
does for ``clip_run_samples`` samples in a row.  A real ADC's rail toggles by
about one count, so values within ``rail_jitter_lsb`` counts of the extreme
count as "at the rail"; the count (LSB) is read from the data (the smallest
step between distinct values near the extreme).  Only extremes beyond
``min_rail_dps`` (the smallest common MEMS range is ±125 °/s) are considered,
so a quantised gyro at rest is never flagged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.recording.errors import SampleError
from wheelcal.recording.samples import percent, rows_all, rows_any, run_lengths

RADPS_PER_DPS = np.pi / 180.0


@dataclass(frozen=True)
class GyroPolicy:
    """Thresholds of the gyro checks (see the module table)."""

    max_plausible_dps: float = 4000.0
    #: A sample this many robust σ (and ``outlier_floor_dps``) from the running median of
    #: five is a gross outlier, or one beyond ``max_plausible_dps`` whose neighbours are not.
    outlier_sigmas: float = 25.0
    outlier_floor_dps: float = 100.0
    #: More outliers than this fraction: not glitches but a wrong unit or a broken channel.
    max_outlier_fraction: float = 0.001
    full_scale_tolerance: float = 1.02
    clip_margin: float = 0.995
    clip_run_samples: int = 3
    min_rail_dps: float = 120.0
    rail_jitter_lsb: float = 1.5
    #: Largest jitter window, as a fraction of the rail value (a sparse tail is not a count).
    max_lsb_fraction: float = 0.005


def align_to_samples(
    raw_time_ns: np.ndarray,
    raw_accel: np.ndarray,
    raw_gyro: np.ndarray,
    kept_time_ns: np.ndarray,
) -> np.ndarray:
    """The gyro rows of the accelerometer samples that survived the checks, by stamp.

    Parameters
    ----------
    raw_time_ns, raw_accel, raw_gyro:
        The decoded data, in file order: stamps (N,), accelerometer (N, 3),
        gyro (N, 3) with NaN rows where absent.
    kept_time_ns:
        The sorted, unique stamps of the cleaned accelerometer samples (M,);
        each is one of ``raw_time_ns``.

    Returns
    -------
    ndarray, shape (M, 3)
        The gyro row per kept stamp: the mean of the finite gyro rows of the
        raw samples with that stamp whose accelerometer row was finite (NaN
        if none).  Rows partly NaN count as NaN.
    """
    t = np.asarray(raw_time_ns, dtype=np.int64)
    kept = np.asarray(kept_time_ns, dtype=np.int64)
    gyro = np.asarray(raw_gyro, dtype=float)
    if t.size == kept.size and np.array_equal(t, kept):
        return gyro.copy()  # nothing was repaired: the common case
    usable = rows_all(np.isfinite(np.asarray(raw_accel)))
    t, gyro = t[usable], gyro[usable]
    order = np.argsort(t, kind="stable")
    t, gyro = t[order], gyro[order]
    unique_t, first = np.unique(t, return_index=True)
    finite = rows_all(np.isfinite(gyro))
    sums = np.add.reduceat(np.where(finite[:, None], gyro, 0.0), first, axis=0)
    counts = np.add.reduceat(finite.astype(np.int64), first)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = sums / counts[:, None]
    means[counts == 0] = np.nan
    at = np.searchsorted(unique_t, kept)
    if np.any(at >= unique_t.size) or not np.array_equal(
        unique_t[np.minimum(at, unique_t.size - 1)], kept
    ):
        raise ValueError("a kept stamp is not among the raw stamps")
    return means[at]


def check_gyro(
    path: str,
    gyro_radps: np.ndarray,
    full_scale_dps: float | None,
    policy: GyroPolicy | None = None,
    unit_hint: str = "",
) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """Judge the aligned gyro rows: left-out rows NaN, or no gyro, with notes; or refuse.

    Parameters
    ----------
    path:
        The file (and topic), for messages.
    gyro_radps:
        (N, 3) rad/s, NaN where absent.
    full_scale_dps:
        The gyro's stated range (±°/s), or ``None``.
    policy:
        Thresholds (:class:`GyroPolicy`).
    unit_hint:
        How to state the unit correctly in this file format, for the refusal.

    Returns
    -------
    gyro : ndarray (N, 3) or None
        Rows all finite or all NaN (the :class:`~wheelcal.recording.Recording`
        convention); ``None`` when the channel carries nothing usable.
    notes : tuple of str
        What was left out, and why.

    Raises
    ------
    SampleError
        Readings no MEMS gyroscope gives (a wrong unit) or beyond the stated range.
    """
    policy = policy or GyroPolicy()
    w = np.array(gyro_radps, dtype=float)
    n = w.shape[0]
    notes: list[str] = []
    bad = ~rows_all(np.isfinite(w))
    w[bad] = np.nan
    valid = ~bad
    if not np.any(valid):
        return None, ("gyro: no usable value in the channel; recording read without a gyro",)
    if not np.any(w[valid]):
        return None, (
            "gyro: angular velocity is exactly zero throughout (an accelerometer-only driver); "
            "recording read without a gyro",
        )
    if np.any(bad):
        notes.append(
            f"gyro: {int(bad.sum())} of {n} samples ({percent(int(bad.sum()), n)}) have no "
            "reading (absent from their message, or NaN/inf); left out"
        )
    outliers = _gross_outliers(w, valid, policy)
    if outliers.any():
        count = int(outliers.sum())
        w[outliers] = np.nan
        valid &= ~outliers
        worst = float(np.nanmax(np.abs(np.asarray(gyro_radps, dtype=float)[outliers])))
        notes.append(
            f"gyro: {count} of {n} samples ({percent(count, n)}) far from their neighbours "
            f"(largest {worst:.3g} rad/s: a logger's glitch); left out"
        )
    _check_range(path, w[valid], full_scale_dps, policy, unit_hint)
    clipped, how = _clipped_rows(w, valid, full_scale_dps, policy)
    count = int(clipped.sum())
    if count:
        w[clipped] = np.nan
        notes.append(
            f"gyro: {count} of {n} samples ({percent(count, n)}) clipped {how}; left out "
            "(their accelerometer samples are kept)"
        )
        if not np.any(np.isfinite(w[:, 0])):
            notes.append("gyro: every reading is clipped; recording read without a gyro")
            return None, tuple(notes)
    return w, tuple(notes)


def _gross_outliers(w: np.ndarray, valid: np.ndarray, policy: GyroPolicy) -> np.ndarray:
    """Isolated rows far from their neighbours (bit errors, glitches): a boolean row mask.

    A row is one when an axis differs from the running median of five valid rows
    (its own and two each side) by more than ``outlier_sigmas`` robust σ of that
    difference and ``outlier_floor_dps``.  A wheel's rate changes by far less
    between neighbouring samples.  Too many (``max_outlier_fraction``): none are
    taken — a wrong unit or a broken channel is for the range check to name.
    """
    rows = np.flatnonzero(valid)
    out = np.zeros(w.shape[0], dtype=bool)
    if rows.size < 5:
        return out
    x = w[rows]
    padded = np.concatenate([x[:1], x[:1], x, x[-1:], x[-1:]])
    windows = np.stack([padded[k : k + x.shape[0]] for k in range(5)])  # (5, m, 3)
    residual = np.abs(x - np.median(windows, axis=0))
    sigma = 1.4826 * np.median(residual, axis=0)
    limit = np.maximum(policy.outlier_sigmas * sigma, policy.outlier_floor_dps * RADPS_PER_DPS)
    beyond = rows_any(residual > limit)
    if not np.any(beyond) or beyond.sum() > policy.max_outlier_fraction * x.shape[0]:
        return out
    out[rows[beyond]] = True
    return out


def _check_range(path, w, full_scale_dps, policy, unit_hint) -> None:
    peak = float(np.max(np.abs(w)))
    peak_dps = peak / RADPS_PER_DPS
    hint = f"; {unit_hint}" if unit_hint else ""
    if peak_dps > policy.max_plausible_dps:
        raise SampleError(
            path,
            f"the gyro reads up to {peak:.4g} rad/s ({peak_dps:.4g} °/s), beyond any MEMS "
            f"gyroscope (±{policy.max_plausible_dps:g} °/s): the values look like deg/s "
            f"read as rad/s{hint}",
        )
    if full_scale_dps is not None and peak_dps > policy.full_scale_tolerance * full_scale_dps:
        raise SampleError(
            path,
            f"the gyro reads up to {peak_dps:.4g} °/s, beyond its stated range "
            f"gyro_full_scale_dps = ±{full_scale_dps:g} °/s: the unit or the range is stated "
            f"wrongly{hint}",
        )


def _clipped_rows(w, valid, full_scale_dps, policy) -> tuple[np.ndarray, str]:
    if full_scale_dps is not None:
        limit = policy.clip_margin * full_scale_dps * RADPS_PER_DPS
        with np.errstate(invalid="ignore"):
            clipped = rows_any(np.abs(w) >= limit) & valid
        return clipped, f"at the gyro range ±{full_scale_dps:g} °/s"
    clipped = np.zeros(w.shape[0], dtype=bool)
    rows = np.flatnonzero(valid)
    rails = []
    for k in range(3):
        x = w[rows, k]
        floor = policy.min_rail_dps * RADPS_PER_DPS
        for side, extreme in ((1, float(x.max())), (-1, float(x.min()))):
            if side * extreme < floor:  # a rail is +full scale on top, −full scale below
                continue
            tol = policy.rail_jitter_lsb * _count_size(x, extreme, policy)
            at = x >= extreme - tol if side > 0 else x <= extreme + tol
            longest = np.max(run_lengths(at), initial=0)
            if at.sum() >= policy.clip_run_samples and longest >= policy.clip_run_samples:
                clipped[rows[at]] = True
                rails.append(f"{'xyz'[k]} = {extreme:+.4g}")
    return clipped, "at the rails " + ", ".join(rails) + " rad/s (runs at the extreme value)"


def _count_size(x: np.ndarray, extreme: float, policy: GyroPolicy) -> float:
    """One ADC count near ``extreme``: the smallest step between distinct values there."""
    span = policy.max_lsb_fraction * abs(extreme)
    near = x[np.abs(x - extreme) <= 4 * span]
    steps = np.diff(np.unique(near))
    if steps.size == 0:
        return 0.0
    step = float(steps.min())
    return step if step <= span else 0.0
