r"""The overlapping Allan deviation of a sensor at rest, and what one reads off it.

For a rate signal :math:`y_k` (here: acceleration, m/s²) sampled at
:math:`f_s`, with phase :math:`x_0 = 0`, :math:`x_{k+1} = x_k + y_k / f_s`
and :math:`\tau = m / f_s`, the overlapping Allan variance is

.. math::

    \sigma^2(\tau) = \frac{1}{2 \tau^2 (N - 2m)}
        \sum_{i=0}^{N-2m-1} \left(x_{i+2m} - 2 x_{i+m} + x_i\right)^2

over the :math:`N` phase points — exactly ``allantools.oadev(y, rate=f_s,
data_type="freq", taus=m / f_s)`` (the same phase, the same sum, the same
normalisation; tested against it).  The sums and counts are additive over
disjoint stretches of data (:class:`AllanSums`), so the rests before the
push and after the stop pool into one curve without bridging the spin.

Read-outs (IEEE Std 952, the terms of Kalibr's ``imu.yaml``):

* **white noise density** N (m/s²/√Hz): :math:`\sigma(\tau) = N/\sqrt{\tau}`,
  read at τ = 1 s (interpolated log-log between the τ around it).  For
  discrete white noise of σ_d at f_s it equals :math:`\sigma_d/\sqrt{f_s}`,
  Kalibr's convention.  Rests shorter than 2 s do not reach τ = 1 s: N is
  then extrapolated along the −½ slope from the longest τ (flagged);
* **bias instability** B (m/s²): the flat floor :math:`\sigma_{min} =
  \sqrt{2\ln 2/\pi}\,B \approx 0.664\,B`.  When the deviation is still
  falling at the longest τ — no later τ above the minimum by two of its
  own σ — the minimum is not a floor and B is an upper bound (flagged).
  Only τ with ≥ 8 whole intervals of data behind them are searched: the last
  octaves rest on one or two and scatter by a factor 2–3;
* **random walk** K (m/s³/√Hz, Kalibr's ``accelerometer_random_walk``):
  :math:`\sigma(\tau) = K\sqrt{\tau/3}`.  The Allan variances of independent
  processes add, so :math:`K^2 \tau / 3 \le \sigma^2(\tau)` at every τ and
  :math:`K \le \min_\tau \sigma(\tau)\sqrt{3/\tau}`: that bound is reported,
  and called an estimate only when the deviation rises along the +½ slope
  over the longest τ (a least-squares slope above 0.35 over the last 16× of
  τ; rests are usually too short for that).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: σ_min = √(2 ln 2 / π) · B at the flicker floor (IEEE Std 952).
BIAS_INSTABILITY_FACTOR = float(np.sqrt(2.0 * np.log(2.0) / np.pi))
#: The τ at which the white noise density is read, s.
WHITE_NOISE_TAU_S = 1.0
#: Slope (log σ per log τ) above which the long-τ end counts as a random walk's rise.
RANDOM_WALK_SLOPE = 0.35
#: The long-τ end whose slope is judged: τ within this factor of the longest usable.
LONG_TAU_SPAN = 16.0
#: A τ is usable for the floor and the random walk with this many whole intervals of
#: data behind it (the last octaves rest on one or two: σ off by a factor of 2–3).
MIN_INTERVALS = 8


def octave_factors(samples: int, rate_hz: float | None = None) -> np.ndarray:
    """Averaging factors m = 1, 2, 4, … (and m at τ = 1 s) that ``samples`` can carry.

    A factor needs at least one second difference: N − 2m ≥ 1 with
    N = samples + 1 phase points.
    """
    top = samples // 2
    factors = set(2 ** np.arange(int(np.log2(top)) + 1)) if top >= 1 else set()
    if rate_hz is not None:
        one_second = round(rate_hz * WHITE_NOISE_TAU_S)
        if 1 <= one_second <= top:
            factors.add(one_second)
    return np.array(sorted(int(m) for m in factors), dtype=np.int64)


@dataclass(frozen=True, eq=False)
class AllanSums:
    """Σ of squared second differences of the phase and their counts, per factor m.

    ``sums`` is (K, axes), ``counts`` (K,); additive over disjoint segments
    sampled at the same rate (:meth:`combined`).
    """

    rate_hz: float
    factors: np.ndarray
    sums: np.ndarray
    counts: np.ndarray
    samples: int

    @classmethod
    def of(cls, y: np.ndarray, rate_hz: float, factors: np.ndarray | None = None) -> AllanSums:
        """The sums of one uniformly sampled stretch ``y`` (N,) or (N, axes)."""
        data = np.asarray(y, dtype=float)
        data = data[:, None] if data.ndim == 1 else data
        if rate_hz <= 0 or not np.isfinite(rate_hz):
            raise ValueError(f"the sample rate must be positive, got {rate_hz!r}")
        n = data.shape[0]
        factors = octave_factors(n, rate_hz) if factors is None else np.asarray(factors)
        # phase x_0 = 0, x_{k+1} = x_k + y_k / f_s (allantools' frequency2phase); the mean
        # is removed first, which cancels in the second differences but keeps x small.
        phase = np.zeros((n + 1, data.shape[1]))
        np.cumsum((data - data.mean(axis=0)) / rate_hz, axis=0, out=phase[1:])
        sums = np.zeros((factors.size, data.shape[1]))
        counts = np.zeros(factors.size, dtype=np.int64)
        for k, m in enumerate(factors.tolist()):
            count = n + 1 - 2 * m
            if count < 1:
                continue
            d = phase[2 * m :] - 2.0 * phase[m : m + count] + phase[:count]
            sums[k] = np.einsum("ij,ij->j", d, d)
            counts[k] = count
        return cls(float(rate_hz), factors, sums, counts, n)

    @staticmethod
    def combined(parts: list[AllanSums]) -> AllanSums | None:
        """Pool disjoint segments of one rate: sums and counts added per factor m."""
        parts = [p for p in parts if p is not None and p.counts.any()]
        if not parts:
            return None
        rate = parts[0].rate_hz
        if any(abs(p.rate_hz - rate) > 1e-6 * rate for p in parts):
            raise ValueError("segments of different sample rates cannot be pooled")
        factors = np.unique(np.concatenate([p.factors for p in parts]))
        sums = np.zeros((factors.size, parts[0].sums.shape[1]))
        counts = np.zeros(factors.size, dtype=np.int64)
        for p in parts:
            at = np.searchsorted(factors, p.factors)
            sums[at] += p.sums
            counts[at] += p.counts
        return AllanSums(rate, factors, sums, counts, sum(p.samples for p in parts))

    def deviation(self) -> AllanDeviation:
        """σ(τ) at every factor with at least one second difference."""
        ok = self.counts > 0
        m = self.factors[ok]
        tau = m / self.rate_hz
        adev = np.sqrt(self.sums[ok] / (2.0 * self.counts[ok, None])) / tau[:, None]
        return AllanDeviation(tau, adev, self.counts[ok], self.samples / self.rate_hz)


def overlapping_adev(y: np.ndarray, rate_hz: float, factors=None) -> AllanDeviation:
    """Overlapping Allan deviation of rate data ``y`` (allantools' ``oadev``, ``data_type="freq"``).

    Parameters
    ----------
    y:
        Samples (N,) or (N, axes), uniformly sampled at ``rate_hz``.
    rate_hz:
        Sample rate, Hz.
    factors:
        Averaging factors m (τ = m / rate_hz); default :func:`octave_factors`.
    """
    return AllanSums.of(y, rate_hz, factors).deviation()


@dataclass(frozen=True, eq=False)
class AllanDeviation:
    """σ(τ) per axis, in the unit of the data (m/s² for an accelerometer)."""

    tau_s: np.ndarray  # (K,)
    adev: np.ndarray  # (K, axes)
    counts: np.ndarray  # (K,) second differences behind each σ
    duration_s: float  # data behind the curve

    def white_noise_density(self) -> tuple[np.ndarray, bool]:
        """(N per axis in unit/√Hz, whether it was read at τ = 1 s rather than extrapolated)."""
        tau, adev = self.tau_s, self.adev
        if tau.size == 0:
            return np.full(adev.shape[1], np.nan), False
        if tau[-1] >= WHITE_NOISE_TAU_S:
            hi = int(np.searchsorted(tau, WHITE_NOISE_TAU_S))
            if tau[hi] == WHITE_NOISE_TAU_S or hi == 0:
                return adev[hi] * np.sqrt(tau[hi]), True
            lo = hi - 1
            w = np.log(WHITE_NOISE_TAU_S / tau[lo]) / np.log(tau[hi] / tau[lo])
            return np.exp((1 - w) * np.log(adev[lo]) + w * np.log(adev[hi])), True
        return adev[-1] * np.sqrt(tau[-1] / WHITE_NOISE_TAU_S), False

    def _usable(self) -> np.ndarray:
        """τ with ≥ MIN_INTERVALS intervals of data behind them (at least the shortest τ)."""
        usable = self.tau_s * MIN_INTERVALS <= self.duration_s
        usable[0] = True
        return usable

    def bias_instability(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(B per axis, the τ of the minimum, whether that minimum is a floor, not a bound)."""
        usable = self._usable()
        tau, adev = self.tau_s[usable], self.adev[usable]
        at = np.argmin(adev, axis=0)
        axes = np.arange(adev.shape[1])
        lowest = adev[at, axes]
        # A floor: the deviation rises again beyond the minimum by more than two of its own σ
        # (relative σ of an overlapping ADEV ≈ 1/√(2·edf), edf ≈ 1.5·T/τ for white noise).
        rel_sigma = 1.0 / np.sqrt(3.0 * self.duration_s / tau)
        above = adev > lowest * (1.0 + 2.0 * rel_sigma[:, None])
        later = np.arange(tau.size)[:, None] > at
        return lowest / BIAS_INSTABILITY_FACTOR, tau[at], np.any(above & later, axis=0)

    def random_walk(self) -> tuple[np.ndarray, np.ndarray]:
        """(K per axis — m/s³/√Hz for data in m/s² — and whether the rise is seen, not a bound)."""
        usable = self._usable()
        tau, adev = self.tau_s[usable], self.adev[usable]
        bound = np.min(adev * np.sqrt(3.0 / tau[:, None]), axis=0)
        seen = np.zeros(adev.shape[1], dtype=bool)
        tail = tau >= tau[-1] / LONG_TAU_SPAN
        if np.count_nonzero(tail) >= 2:
            # the log-log slope over the long-τ end (least squares: the last points are noisy)
            x = np.log(tau[tail])
            x = x - x.mean()
            slope = x @ np.log(adev[tail]) / (x @ x)
            seen = slope > RANDOM_WALK_SLOPE
        return bound, seen
