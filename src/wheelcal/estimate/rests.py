"""Rest segments: where the wheel stands still, before the push and after the stop.

They are evidence the fit never saw, so they can judge it:

* their scatter is the sensor's own **noise floor** — independent of the
  model, unlike an AR noise model fitted to the residual, which absorbs
  whatever the model misses (:mod:`wheelcal.session.noise_reference`);
* their mean is a static reading of gravity, which a calibration must turn
  into |a| = g (:mod:`wheelcal.session.rest_check`).

Detection needs no unit or mounting: the signal is cut into blocks of
~0.1 s; a block is *still* when its mean differs from the previous block's
by no more than the noise explains (a turning wheel moves its rotating
gravity component by g sinα·ω·0.1 s ≫ the noise between blocks, even at
1.5 rad/s).  Runs of still blocks lasting ``min_duration_s`` outside the
free-spin window, trimmed by one block at each end, are rests.  With a gyroscope a
still block must also show a wheel that does not turn: a car's wheel spinning fast
and steadily has steady block means too (``REST_MAX_RATE_RADPS``).  A block with
samples left out inside it (clipped: a wheel at rest never clips) is no rest either.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.allan import AllanSums
from wheelcal.estimate.joint import NoiseModel, centred_rows, column_means
from wheelcal.recording import Recording

#: Block length for the stillness test.
BLOCK_S = 0.1
#: A block is still when |Δmean| < this × the noise expected of a difference of means.
STILL_FACTOR = 5.0
#: With a gyroscope a rest is also a wheel that does not turn: a block's median |ω| below
#: this (rad/s), most of its gyro rows read.  A wheel spinning fast and steadily has
#: steady block means too (its gravity term averages out within a block), and a gyro
#: that clipped there has left its rows out (NaN).
REST_MAX_RATE_RADPS = 0.5


@dataclass(frozen=True, eq=False)
class RestSegment:
    """One stretch of stillness (recording times, samples in m/s²)."""

    start_s: float
    end_s: float
    samples: int
    mean_mps2: np.ndarray  # (3,)
    mean_std_mps2: np.ndarray  # (3,) σ of the mean (coloured noise included)
    noise_std_mps2: np.ndarray  # (3,) marginal noise std
    noise_dof: float  # effective samples behind noise_std (for its uncertainty)
    #: The overlapping Allan sums of the segment (:mod:`wheelcal.estimate.allan`), pooled
    #: over the rests for the noise density, bias instability and random walk.
    allan: AllanSums | None = None
    #: The gyroscope's noise std per axis over the rest (rad/s), when there is a gyro.
    gyro_noise_std_radps: np.ndarray | None = None
    #: The gyroscope's mean per axis over the rest (rad/s) and its σ (noise std / √n):
    #: a static reading of its bias and G·a (:mod:`wheelcal.estimate.joint.gyro_rests`).
    gyro_mean_radps: np.ndarray | None = None
    gyro_mean_std_radps: np.ndarray | None = None
    #: The gyroscope's overlapping Allan sums over the rest (rad/s), pooled over the rests
    #: for its random walk's bound and the check of its noise density.
    gyro_allan: AllanSums | None = None

    @property
    def mid_s(self) -> float:
        """Centre of the segment."""
        return 0.5 * (self.start_s + self.end_s)


def find_rests(
    recording: Recording,
    exclude_s: tuple[float, float] | None = None,
    min_duration_s: float = 1.0,
    margin_s: float = 0.5,
) -> tuple[RestSegment, ...]:
    """The rest segments of ``recording`` outside ``exclude_s`` (the free-spin window)."""
    t = recording.time_s
    v = recording.accel_mps2
    rate = recording.rate_hz
    block = max(10, round(BLOCK_S * rate))
    n_blocks = t.size // block
    if n_blocks < 3:
        return ()
    means, stds = block_statistics(v, block)
    # A difference of two block means has σ ≈ √(2/n)·σ_block for white noise;
    # low-pass noise makes block means noisier, which STILL_FACTOR allows for.
    limit = STILL_FACTOR * np.sqrt(2.0 / block) * np.maximum(stds[1:], stds[:-1])
    step_ok = np.all(np.abs(np.diff(means, axis=0)) <= limit + 1e-12, axis=1)
    still = np.concatenate([step_ok[:1], step_ok])  # block b vs block b − 1
    still &= _without_holes(t, block, n_blocks)
    gyro = getattr(recording, "gyro_radps", None)
    if gyro is not None:
        still &= _gyro_quiet(gyro, block, n_blocks)
    # Times of blocks; remove anything near the free spin.
    block_t0 = t[: n_blocks * block : block]
    block_t1 = t[block - 1 : n_blocks * block : block]
    if exclude_s is not None:
        lo, hi = exclude_s[0] - margin_s, exclude_s[1] + margin_s
        still &= (block_t1 < lo) | (block_t0 > hi)
    segments = []
    edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
    for first, stop in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        first, last = first + 1, stop - 2  # trim one block at each end
        if last < first:
            continue
        # A rest is homogeneous: drop end blocks noisier than the segment's typical
        # block (a wheel coming to rest still vibrates).
        typical = np.median(stds[first : last + 1], axis=0)
        while first <= last and np.any(stds[first] > 1.5 * typical):
            first += 1
        while last >= first and np.any(stds[last] > 1.5 * typical):
            last -= 1
        i0, i1 = first * block, (last + 1) * block
        if t[i1 - 1] - t[i0] < min_duration_s:
            continue
        segments.append(_segment(t[i0:i1], v[i0:i1], rate, None if gyro is None else gyro[i0:i1]))
    return tuple(segments)


def _without_holes(t: np.ndarray, block: int, n_blocks: int) -> np.ndarray:
    """Per block: no sample left out inside it (a clipped one: a wheel at rest never clips)."""
    stamps = t[: n_blocks * block].reshape(n_blocks, block)
    return np.diff(stamps, axis=1).max(axis=1) <= 1.5 * float(np.median(np.diff(t)))


def _gyro_quiet(gyro_radps: np.ndarray, block: int, n_blocks: int) -> np.ndarray:
    """Per block: most gyro rows read, and their median |ω| below ``REST_MAX_RATE_RADPS``."""
    size = np.linalg.norm(gyro_radps[: n_blocks * block], axis=1).reshape(n_blocks, block)
    finite = np.isfinite(size)
    median = np.median(np.where(finite, size, np.inf), axis=1)  # a row left out counts as fast
    return (finite.mean(axis=1) >= 0.5) & (median < REST_MAX_RATE_RADPS)


def block_statistics(v: np.ndarray, block: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and std (ddof 1) per axis of each whole block of ``block`` samples: (blocks, 3).

    The blocks are laid out (axis, block, sample), each block's samples contiguous:
    numpy reduces the middle axis of (block, sample, axis) several times slower.
    """
    n_blocks = v.shape[0] // block
    blocks = np.ascontiguousarray(v[: n_blocks * block].T).reshape(3, n_blocks, block)
    return blocks.mean(axis=2).T, blocks.std(axis=2, ddof=1).T


def _segment(
    t: np.ndarray, v: np.ndarray, rate_hz: float | None = None, gyro: np.ndarray | None = None
) -> RestSegment:
    mean = column_means(v)
    centred = centred_rows(v, mean)  # (3, n)
    noise = NoiseModel.estimate(centred.T, max_order=6)
    n = t.size
    # σ of a mean of n correlated samples: long-run std / √n.
    mean_std = noise.long_run_std_mps2 / np.sqrt(n)
    rate_hz = rate_hz or float(1.0 / np.median(np.diff(t)))
    return RestSegment(
        start_s=float(t[0]),
        end_s=float(t[-1]),
        samples=int(n),
        mean_mps2=mean,
        mean_std_mps2=mean_std,
        noise_std_mps2=np.array([np.std(row, ddof=1) for row in centred]),
        noise_dof=float(n * np.min(noise.effective_sample_fraction)),
        allan=AllanSums.of(v, rate_hz),
        **_gyro_statistics(gyro, rate_hz),
    )


def _gyro_statistics(gyro: np.ndarray | None, rate_hz: float) -> dict:
    """The gyro's std, mean, σ of the mean and Allan sums per axis over a rest's valid rows.

    Empty (the fields stay None) without a gyro or with fewer than 10 valid rows.
    The Allan sums need evenly spaced rows: a rest with a row left out has none.
    """
    if gyro is None:
        return {}
    finite = np.all(np.isfinite(gyro), axis=1)
    valid = gyro[finite]
    if valid.shape[0] < 10:
        return {}
    std = np.std(valid, axis=0, ddof=1)
    return {
        "gyro_noise_std_radps": std,
        "gyro_mean_radps": valid.mean(axis=0),
        "gyro_mean_std_radps": std / np.sqrt(valid.shape[0]),
        "gyro_allan": AllanSums.of(valid, rate_hz) if finite.all() else None,
    }


def pooled_noise_std(rests: tuple[RestSegment, ...]) -> tuple[np.ndarray, float] | None:
    """Noise std per axis pooled over the rests (weighted by samples), and its dof."""
    if not rests:
        return None
    weights = np.array([r.samples - 1 for r in rests], dtype=float)
    var = np.array([r.noise_std_mps2**2 for r in rests])
    pooled = np.sqrt(weights @ var / weights.sum())
    return pooled, float(sum(r.noise_dof for r in rests))
