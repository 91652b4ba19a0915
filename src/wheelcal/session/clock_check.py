"""Is the sample clock right?  The stamped rate against its nominal rate, and the gyro.

A wheel spinning freely cannot see a clock error: stamps stretched by a factor
s make the fit read the spin as ω/s, the centripetal acceleration r ω² as
r ω²/s², and absorb it into the gains — exactly a radius error
(:mod:`wheelcal.estimate.joint.systematic`: ε ≡ −2ε in r).  The systematic
budget assumes a crystal, ±100 ppm; a clock 2 % off biases every gain by 4 %,
some 11 σ, with nothing in the residual to show it.  Two things can show it:

* **The stamped rate against its nominal rate.**  Sensors sample at round
  rates (100, 120, 200, 400, 500, 1000 Hz, the 12.5·2ᵏ Hz of Bosch and Analog
  Devices parts, …, :data:`NOMINAL_RATES_HZ`).  Samples stamped at 204.08 Hz
  are 2 % from 200 Hz: either the sensor really samples 2 % fast (its stamps
  are right: nothing is biased), or it samples at 200 Hz and the clock that
  stamped them runs 2 % slow.  Only the second biases the calibration, and
  the stamps alone cannot tell the two apart.
* **The gyroscope**, where there is one: it reads the wheel's rate in true
  seconds, the accelerometer's fit in stamped ones, so a clock error s scales
  the gyro's fitted scale k by s.  A gyro's own sensitivity is uncertain by
  about :data:`GYRO_SCALE_CLASS_STD` (1 %), so the gyro weighs the two
  explanations: the stamped rate's offset explaining k's (then the clock is
  confirmed) or k being the gyro's own (then the stamps are right).

The verdicts (:class:`ClockCheck`): nothing seen; a stamped rate off nominal
that would bias the calibration by more than :data:`BIAS_SIGMAS` σ — a warning
naming the clock, or the ``clock`` refusal when the gyro confirms it; cleared
by the gyro; or, at the nominal rate, a gyro scale far from 1 (stamps made
from a sample counter and a nominal rate, while the sensor samples off it) —
a warning that names both causes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint import CalibrationResult
from wheelcal.model import AXES
from wheelcal.recording import CalibrationRefused

#: Round sample rates (Hz): 1–1.2–1.25–1.5–2–2.5–3–4–5–6–8 × 10ᵏ, the 12.5·2ᵏ family and
#: ST's LSM9DS1 rates (14.9, 59.5, 119, 238, 476, 952 Hz).  ST's LSM6 rates (104, 208,
#: 416, 833 Hz) lie 4 % from 100/200/400/800: beyond :data:`MAX_OFFSET`, not judged.
NOMINAL_RATES_HZ = tuple(
    sorted(
        {
            round(m * 10.0**e, 6)
            for e in range(0, 4)
            for m in (1.0, 1.2, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)
        }
        | {12.5 * 2**k for k in range(10)}
        | {14.9, 59.5, 119.0, 238.0, 476.0, 952.0}
    )
)
#: A stamped rate further than this from every nominal rate is no evidence either way.
MAX_OFFSET = 0.025
#: A clock error flagged must bias a determined gain or offset by more than this many σ
#: (statistical and systematic together).
BIAS_SIGMAS = 2.0
#: The spread of a MEMS gyro's sensitivity along one axis (datasheets: ±3 %, typically ~1 %).
GYRO_SCALE_CLASS_STD = 0.01
#: The gyro decides between the clock and the sensor's rate beyond this likelihood ratio.
DECISIVE_RATIO = 20.0
#: At the nominal rate, a gyro scale this far from 1 is named (the datasheet's ±3 %).
GYRO_SCALE_TOLERANCE = 0.03


@dataclass(frozen=True)
class ClockCheck:
    """What the stamps and the gyro say about the sample clock (``fit.clock_check``)."""

    stamped_rate_hz: float
    #: The nearest nominal rate within :data:`MAX_OFFSET`, else None (no evidence).
    nominal_rate_hz: float | None
    #: stamped / nominal − 1 (None without a nominal rate).
    rate_offset: float | None
    #: If the offset is the clock's: the shift of the worst determined gain or offset,
    #: in σ (statistical and systematic); None when the clock does not enter (r fitted).
    bias_sigmas: float | None
    #: The parameter that shift is on, and the shift itself.
    worst: str | None
    worst_shift: float | None
    gyro_scale: float | None
    gyro_scale_std: float | None
    #: The gyro's likelihood ratio "the clock is off" : "the sensor samples off nominal".
    likelihood_ratio: float | None
    #: ``ok``, ``rate_off`` (warned), ``confirmed`` (refused), ``cleared`` (the gyro agrees
    #: with the stamps), ``negligible`` (off nominal, but no bias worth a warning) or
    #: ``gyro_off`` (at the nominal rate, the gyro's scale far from 1: warned).
    verdict: str
    warning: str | None = None

    def to_dict(self) -> dict:
        """The calibration JSON's ``fit.clock_check``."""
        out = {
            "stamped_rate_hz": self.stamped_rate_hz,
            "nominal_rate_hz": self.nominal_rate_hz,
            "rate_offset_ppm": None if self.rate_offset is None else 1e6 * self.rate_offset,
            "verdict": self.verdict,
            "bias_sigmas": self.bias_sigmas,
            "worst_parameter": self.worst,
            "worst_shift": self.worst_shift,
            "assumes": (
                "sensors sample at a round nominal rate; the nearest within "
                f"{100 * MAX_OFFSET:g} % is taken as this one's"
            ),
        }
        if self.gyro_scale is not None:
            out["gyro_scale"] = self.gyro_scale
            out["gyro_scale_std"] = self.gyro_scale_std
            out["gyro_likelihood_ratio"] = self.likelihood_ratio
        return out


def stamped_rate_hz(time_s: np.ndarray) -> float:
    """The rate the stamps give: the mean step between neighbours, gaps and repeats left out.

    (Steps within ±25 % of the median: a dropped sample or a stamp repeated by a
    logger does not move it; the mean, unlike the median, is not quantised by
    the stamps' resolution — 120.0048 Hz stays 120.0048 Hz.)
    """
    steps = np.diff(np.asarray(time_s, dtype=float))
    steps = steps[steps > 0]
    if steps.size == 0:
        return float("nan")
    median = float(np.median(steps))
    regular = steps[np.abs(steps - median) <= 0.25 * median]
    return float(1.0 / np.mean(regular))


def nominal_rate(rate_hz: float) -> tuple[float | None, float | None]:
    """(nominal rate, stamped/nominal − 1) for the nearest nominal within :data:`MAX_OFFSET`."""
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        return None, None
    nominal = min(NOMINAL_RATES_HZ, key=lambda f: abs(math.log(rate_hz / f)))
    offset = rate_hz / nominal - 1.0
    if abs(offset) > MAX_OFFSET:
        return None, None
    return nominal, offset


def check_clock(
    result: CalibrationResult, undetermined: set[str], tolerance: float, gyro=None
) -> ClockCheck:
    """The clock check of a fit (``gyro``: its :class:`GyroCalibration`, if any).

    A stamped rate within ``tolerance`` (relative, ``Gates.clock_tolerance``) of
    its nominal rate is taken as the nominal rate.

    Raises :class:`CalibrationRefused` (gate ``clock``) when the gyro confirms a
    clock error that biases the calibration.
    """
    rate = stamped_rate_hz(result.time_s)
    nominal, offset = nominal_rate(rate)
    k = k_std = ratio = None
    if gyro is not None and math.isfinite(gyro.scale):
        k, k_std = float(gyro.scale), float(gyro.scale_std)
    common = dict(stamped_rate_hz=rate, nominal_rate_hz=nominal, rate_offset=offset)
    common.update(gyro_scale=k, gyro_scale_std=k_std)
    if offset is None or abs(offset) <= tolerance:
        return _at_nominal(result, undetermined, common, k)
    # Stamps s × the true time: the rate reads f/s, so s = 1/(1 + offset); the budget's
    # clock error is the stretch s − 1 (in ppm).
    stretch_ppm = 1e6 * (1.0 / (1.0 + offset) - 1.0)
    worst, shift, sigmas = _worst_shift(result, undetermined, stretch_ppm)
    if k is not None:
        corrected = k * (1.0 + offset)  # the gyro's scale if the clock is the cause
        ratio = math.exp(((k - 1.0) ** 2 - (corrected - 1.0) ** 2) / (2 * GYRO_SCALE_CLASS_STD**2))
    common.update(bias_sigmas=sigmas, worst=worst, worst_shift=shift, likelihood_ratio=ratio)
    if sigmas is None or sigmas <= BIAS_SIGMAS:
        return ClockCheck(**common, verdict="negligible")
    if ratio is not None and ratio < 1.0 / DECISIVE_RATIO:
        return ClockCheck(**common, verdict="cleared")
    slow = "slow" if offset > 0 else "fast"
    seen = (
        f"clock: the samples are stamped at {rate:.6g} Hz, {100 * abs(offset):.2f} % "
        f"{'above' if offset > 0 else 'below'} the nominal {nominal:g} Hz. If the sensor samples "
        f"at {nominal:g} Hz, the clock that stamped them runs {100 * abs(offset):.2f} % {slow} "
        f"and the calibration is biased: {worst} by {shift:+.3g} ({sigmas:.0f} σ), every gain "
        f"by ≈ {100 * ((1 + offset) ** -2 - 1):+.1f} %"
    )
    if ratio is not None and ratio > DECISIVE_RATIO:
        raise CalibrationRefused(
            result.source,
            "clock",
            f"{seen[len('clock: ') :]}; the gyro confirms it: it reads the wheel's rate with "
            f"scale {k:.4f}, which the clock error explains ({k * (1 + offset):.4f} once "
            "corrected)",
            f"re-stamp the samples from the sensor's own sample count at {nominal:g} Hz (or "
            "record with an accurate clock); if the sensor does sample at "
            f"{rate:.6g} Hz, raise --clock-tolerance above {abs(offset):.3g}",
        )
    if k is not None:
        why = (
            f"; the gyro cannot tell (its scale {k:.4f}, or {k * (1 + offset):.4f} if the clock "
            f"is off, both within a gyro's ~{100 * GYRO_SCALE_CLASS_STD:g} % sensitivity)"
        )
    else:
        why = "; without a gyro the recording cannot tell"
    text = (
        seen
        + why
        + f". If the sensor really samples at {rate:.6g} Hz (its stamps from an accurate clock), "
        "nothing is wrong"
    )
    return ClockCheck(**common, verdict="rate_off", warning=text)


def _at_nominal(result, undetermined, common: dict, k: float | None) -> ClockCheck:
    """At the nominal rate (or far from any): only a gyro scale far from 1 is worth a word."""
    common.update(bias_sigmas=None, worst=None, worst_shift=None, likelihood_ratio=None)
    if k is None or abs(k - 1.0) <= GYRO_SCALE_TOLERANCE:
        return ClockCheck(**common, verdict="ok")
    stretch_ppm = 1e6 * (k - 1.0)  # if the gyro is exact: the stamps are k × the true time
    worst, shift, sigmas = _worst_shift(result, undetermined, stretch_ppm)
    if sigmas is None or sigmas <= BIAS_SIGMAS:
        return ClockCheck(**common, verdict="ok")
    common.update(bias_sigmas=sigmas, worst=worst, worst_shift=shift)
    text = (
        f"clock: the gyro reads the wheel's rate with scale {k:.4f}, "
        f"{100 * abs(k - 1):.1f} % from 1, beyond a gyro's ±{100 * GYRO_SCALE_TOLERANCE:g} % "
        "sensitivity tolerance: either the gyro is that far off, or the time stamps are "
        f"{100 * abs(k - 1):.1f} % {'long' if k > 1 else 'short'} (stamps made from a sample "
        "count and a nominal rate the sensor does not keep) — then the calibration is biased: "
        f"{worst} by {shift:+.3g} ({sigmas:.0f} σ)"
    )
    return ClockCheck(**common, verdict="gyro_off", warning=text)


def _worst_shift(
    result: CalibrationResult, undetermined: set[str], stretch_ppm: float
) -> tuple[str | None, float | None, float | None]:
    """The determined gain/offset a clock stretch moves most, in σ; (None,)*3 if none.

    First order, from the systematic budget's ``sample_clock`` source (the shift
    per ppm of stretch); absent when the radius is fitted (the clock then moves
    the radius, not the gains).
    """
    budget = result.systematic
    source = next((s for s in budget.sources if s.name == "sample_clock"), None)
    if source is None:
        return None, None, None
    total_sys = dict(zip(budget.names, budget.total_std, strict=True))
    shifts = dict(zip(budget.names, source.shift_per_unit * stretch_ppm, strict=True))
    best = (None, None, None)
    for name in [f"gain_{a}" for a in AXES] + [f"offset_{a}_mps2" for a in AXES]:
        if name in undetermined or name not in shifts:
            continue
        sigma = math.hypot(result.std_of(name), total_sys.get(name, 0.0))
        if not sigma > 0:
            continue
        z = abs(shifts[name]) / sigma
        if best[2] is None or z > best[2]:
            best = (name, float(shifts[name]), float(z))
    return best
