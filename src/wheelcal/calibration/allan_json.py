"""``fit.allan``: the rests' overlapping Allan deviation in a calibration document.

Additive key of ``wheelcal.calibration/1`` and ``wheelcal.sensor_calibration/1``
(present when the recording has rests; see :mod:`wheelcal.estimate.allan`)::

    "allan": {
      "source": "rests", "rests_s", "rate_hz",
      "tau_s": [K], "adev_mps2": [[x, y, z], ...K], "counts": [K],
      "white_noise_density_mps2_rthz": [3], "white_noise_read_at_1s": bool,
      "bias_instability_mps2": [3], "bias_instability_tau_s": [3],
      "bias_instability_is_floor": [3],
      "random_walk_mps3_rthz": [3], "random_walk_seen": [3]
    }

``counts`` (second differences behind each σ) make the curves of several
sessions pool exactly: σ² = Σ nᵢσᵢ² / Σ nᵢ per τ (the same sums as one
curve over all their rests).  A random walk not ``seen`` and a bias
instability not ``is_floor`` are upper bounds (see the estimate module).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from wheelcal.estimate import AllanDeviation, AllanSums


def _floats(values) -> list:
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(values, float).ravel()]


def _rounded(values) -> list:
    """τ and rates to 12 digits: 0.005, not 0.004999999999999005 from a median of float times."""
    return [float(f"{v:.12g}") for v in np.asarray(values, float).ravel()]


def allan_block(sums: AllanSums | None) -> dict | None:
    """The ``fit.allan`` dictionary of pooled rest sums (``None`` without rests)."""
    if sums is None:
        return None
    return deviation_block(sums.deviation(), sums.rate_hz)


def deviation_block(curve: AllanDeviation, rate_hz: float) -> dict | None:
    """The ``fit.allan`` dictionary of one Allan deviation curve."""
    if curve.tau_s.size == 0:
        return None
    density, at_one_second = curve.white_noise_density()
    bias, bias_tau, floor = curve.bias_instability()
    walk, seen = curve.random_walk()
    return {
        "source": "rests",
        "rests_s": _rounded(curve.duration_s)[0],
        "rate_hz": _rounded(rate_hz)[0],
        "tau_s": _rounded(curve.tau_s),
        "adev_mps2": [_floats(row) for row in curve.adev],
        "counts": [int(c) for c in curve.counts],
        "white_noise_density_mps2_rthz": _floats(density),
        "white_noise_read_at_1s": bool(at_one_second),
        "bias_instability_mps2": _floats(bias),
        "bias_instability_tau_s": _rounded(bias_tau),
        "bias_instability_is_floor": [bool(f) for f in floor],
        "random_walk_mps3_rthz": _floats(walk),
        "random_walk_seen": [bool(s) for s in seen],
    }


def rests_allan(rests: Sequence) -> dict | None:
    """``fit.allan`` of the rest segments (:class:`~wheelcal.estimate.rests.RestSegment`)."""
    return allan_block(AllanSums.combined([getattr(r, "allan", None) for r in rests]))


def curve_of(block: Mapping) -> AllanDeviation:
    """The Allan deviation curve stored in a ``fit.allan`` block."""
    return AllanDeviation(
        tau_s=np.asarray(block["tau_s"], dtype=float),
        adev=np.asarray(block["adev_mps2"], dtype=float),
        counts=np.asarray(block["counts"], dtype=np.int64),
        duration_s=float(block["rests_s"]),
    )


def of_the_common_rate(blocks: Sequence[Mapping | None]) -> tuple[float, list[Mapping]]:
    """The most common ``rate_hz`` among the blocks given, and those blocks (none: [])."""
    blocks = [b for b in blocks if b]
    if not blocks:
        return float("nan"), []
    rates = [round(float(b["rate_hz"]), 6) for b in blocks]
    rate = max(set(rates), key=rates.count)
    return rate, [b for b, r in zip(blocks, rates, strict=True) if r == rate]


def pooled_allan(blocks: Sequence[Mapping | None]) -> dict | None:
    """One ``fit.allan`` from several sessions' (of the most common rate; exact pooling)."""
    rate, same = of_the_common_rate(blocks)
    if not same:
        return None
    taus = sorted({t for b in same for t in b["tau_s"]})
    weighted = np.zeros((len(taus), len(same[0]["adev_mps2"][0])))
    counts = np.zeros(len(taus), dtype=np.int64)
    for b in same:
        at = np.searchsorted(taus, b["tau_s"])
        n = np.asarray(b["counts"], dtype=np.int64)
        weighted[at] += n[:, None] * np.asarray(b["adev_mps2"], dtype=float) ** 2
        counts[at] += n
    curve = AllanDeviation(
        tau_s=np.asarray(taus),
        adev=np.sqrt(weighted / counts[:, None]),
        counts=counts,
        duration_s=float(sum(b["rests_s"] for b in same)),
    )
    return deviation_block(curve, rate)
