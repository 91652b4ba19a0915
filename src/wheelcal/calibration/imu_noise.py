r"""``imu_noise``: the IMU's noise in the terms of Kalibr's ``imu.yaml`` (additive JSON block).

Kalibr's IMU noise model (its wiki, "IMU Noise Model"; ``ImuParameters`` in
``kalibr_common/ConfigReader.py``) is continuous white noise of density σ_c
plus a bias random walk of density σ_b.  Sampled at f_s, the white noise of
one sample has σ_d = σ_c·√f_s — Kalibr's reader computes exactly that,
``noise_density / sqrt(1 / update_rate)`` — so

.. math::

    \sigma_c = \sigma_d / \sqrt{f_s}

with σ_d the **per-sample σ of the white noise**, which the data give well:
the rests (the sensor still before the push and after the stop, no model at
all) to ±1/√(2(n − 1)) of itself, ≈ ±2 % for 6 s at 200 Hz; without rests,
the fit's residual over the spin (its noise model's marginal σ: the sensor's
noise plus whatever the model misses, so an upper side).  Units: m/s²/√Hz
for the accelerometer, rad/s/√Hz for the gyroscope (Kalibr's).

The overlapping Allan deviation of the rests reads the same density at
τ = 1 s (σ(τ) = σ_c/√τ for white noise) but from one or two dozen
independent differences: its own relative σ is 1/√(2·edf), with edf the
equivalent degrees of freedom of an overlapping Allan variance of white
noise (NIST SP 1065, Table 5: [3(N−1)/(2m) − 2(N−2)/N]·4m²/(4m²+5) for N
phase points and averaging factor m, summed over the rests) — ±30 % for 6 s
of rests.  So it is the **check**, not the source: ``allan_z`` is the
difference in units of the Allan read-out's own σ (|z| ≲ 2 for white
noise; a coloured or drifting sensor shows larger).

The **random walk** (m/s³/√Hz, rad/s²/√Hz) needs rests far longer than a
calibration has: the variances of independent processes add, so
σ²(τ) ≥ K²τ/3 at every τ and K ≤ min_τ σ(τ)·√(3/τ) — an **upper bound**
(``random_walk_is_upper_bound``), unless the deviation is seen to rise along
the +½ slope (:mod:`wheelcal.estimate.allan`).  In a Kalibr config an upper
bound is the conservative choice (the bias may wander more than it does).

allan_variance_ros writes the same ``imu.yaml`` keys; its log calls the
white-noise densities "Velocity Random Walk" and "Angle Random Walk" and the
random walks "Accel Random Walk" and "Rate Random Walk"
(:data:`ALLAN_VARIANCE_ROS_NAMES`).

The block::

    "imu_noise": {
      "rate_hz", "definition",
      "accelerometer": {"source": "rests"|"residual", "samples", "white_std_mps2": [3],
                        "white_std_rel_std", "noise_density_mps2_rthz": [3],
                        "allan_density_mps2_rthz": [3]|null, "allan_rel_std"|null,
                        "allan_z": [3]|null, "random_walk_mps3_rthz": [3]|null,
                        "random_walk_is_upper_bound": [3]|null},
      "gyroscope": {... the same in rad/s: "white_std_radps", "noise_density_radps_rthz",
                    "allan_density_radps_rthz", "random_walk_radps2_rthz", ...}
    }
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from wheelcal.calibration.allan_json import of_the_common_rate
from wheelcal.estimate import WHITE_NOISE_TAU_S, AllanSums

#: The per-sensor sub-blocks: JSON name, unit of a sample, of the density, of the walk.
SENSORS = {
    "accelerometer": ("mps2", "mps2_rthz", "mps3_rthz"),
    "gyroscope": ("radps", "radps_rthz", "radps2_rthz"),
}
#: Kalibr's ``imu.yaml`` keys → (sensor block, field) of ``imu_noise``.
KALIBR_KEYS = {
    "accelerometer_noise_density": ("accelerometer", "noise_density"),
    "accelerometer_random_walk": ("accelerometer", "random_walk"),
    "gyroscope_noise_density": ("gyroscope", "noise_density"),
    "gyroscope_random_walk": ("gyroscope", "random_walk"),
}
#: What allan_variance_ros's log (``output.log``) calls each of Kalibr's keys (its
#: ``imu.yaml`` uses Kalibr's own names).
ALLAN_VARIANCE_ROS_NAMES = {
    "accelerometer_noise_density": "Velocity Random Walk",
    "accelerometer_random_walk": "Accel Random Walk",
    "gyroscope_noise_density": "Angle Random Walk",
    "gyroscope_random_walk": "Rate Random Walk",
}
DEFINITION = (
    "Kalibr's: noise density = the white noise's sigma per sample / sqrt(rate) (its reader's "
    "noise_density / sqrt(1/update_rate) is that sigma again); the Allan deviation at tau = 1 s "
    "is the check; random walk = the rests' Allan bound min sigma(tau)*sqrt(3/tau) unless seen"
)


def _num(x) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else float(x)


def _vec(values) -> list | None:
    return None if values is None else [_num(v) for v in np.asarray(values, float).ravel()]


def white_adev_edf(samples: Sequence[int], factor: int) -> float:
    """Equivalent degrees of freedom of an overlapping Allan variance of white noise.

    NIST SP 1065 (Riley), Table 5, white FM: edf = [3(N−1)/(2m) − 2(N−2)/N]·4m²/(4m²+5)
    for N phase points (samples + 1) and averaging factor m, summed over segments of
    ``samples`` each (disjoint rests pool their sums: their edf add).
    """
    m = int(factor)
    total = 0.0
    for n in samples:
        phase = int(n) + 1
        if phase - 2 * m < 1:
            continue
        edf = (3 * (phase - 1) / (2 * m) - 2 * (phase - 2) / phase) * 4 * m * m / (4 * m * m + 5)
        total += max(edf, 0.0)
    return total


def _white_noise(
    rests_std: list[np.ndarray], rests_samples: list[int], fallback_std, rate_hz: float
) -> tuple[str, int, np.ndarray] | None:
    """(source, samples, per-sample σ per axis): the rests' pooled σ, else the fallback's."""
    if rests_std:
        weights = np.array([n - 1 for n in rests_samples], dtype=float)
        var = np.array([np.asarray(s, float) ** 2 for s in rests_std])
        return "rests", int(sum(rests_samples)), np.sqrt(weights @ var / weights.sum())
    if fallback_std is None:
        return None
    std = np.asarray(fallback_std, dtype=float)
    if std.shape != (3,) or not np.all(np.isfinite(std) & (std > 0)):
        return None
    return "residual", 0, std


def sensor_block(
    kind: str,
    rate_hz: float,
    rests_std: list[np.ndarray],
    rests_samples: list[int],
    allan: AllanSums | None,
    fallback_std=None,
    fallback_samples: int = 0,
) -> dict | None:
    """One sensor's sub-block (``kind``: ``accelerometer`` or ``gyroscope``), or None."""
    sample, density_unit, walk_unit = SENSORS[kind]
    found = _white_noise(rests_std, rests_samples, fallback_std, rate_hz)
    if found is None or not rate_hz or rate_hz <= 0:
        return None
    source, samples, std = found
    samples = samples or int(fallback_samples)
    density = std / math.sqrt(rate_hz)
    rel = 1.0 / math.sqrt(2.0 * max(samples - 1, 1)) if samples else None
    block = {
        "source": source,
        "samples": int(samples),
        f"white_std_{sample}": _vec(std),
        "white_std_rel_std": _num(rel),
        f"noise_density_{density_unit}": _vec(density),
        f"allan_density_{density_unit}": None,
        "allan_rel_std": None,
        "allan_z": None,
        f"random_walk_{walk_unit}": None,
        "random_walk_is_upper_bound": None,
    }
    if allan is not None and allan.counts.any():
        curve = allan.deviation()
        read, at_one_second = curve.white_noise_density()
        factor = round(rate_hz * WHITE_NOISE_TAU_S)
        edf = white_adev_edf(rests_samples, factor) if at_one_second else 0.0
        allan_rel = 1.0 / math.sqrt(2.0 * edf) if edf > 0 else None
        walk, seen = curve.random_walk()
        block.update(
            {
                f"allan_density_{density_unit}": _vec(read),
                "allan_rel_std": _num(allan_rel),
                "allan_z": (_vec((read - density) / (density * allan_rel)) if allan_rel else None),
                f"random_walk_{walk_unit}": _vec(walk),
                "random_walk_is_upper_bound": [not bool(s) for s in seen],
            }
        )
    return block


def imu_noise_block(
    rests: Sequence,
    rate_hz: float | None,
    accel_residual_std=None,
    accel_samples: int = 0,
    gyro_residual_rms=None,
    gyro_samples: int = 0,
) -> dict | None:
    """``imu_noise`` of a session: from its rests (``RestSegment``), else its residuals.

    ``accel_residual_std``: the fit's marginal noise σ (m/s²) over ``accel_samples``;
    ``gyro_residual_rms``: the gyro's residual rms (rad/s) over ``gyro_samples``, when
    there is a gyro — each used only without rests.
    """
    if not rate_hz:
        return None
    accel = sensor_block(
        "accelerometer",
        rate_hz,
        [r.noise_std_mps2 for r in rests],
        [r.samples for r in rests],
        AllanSums.combined([getattr(r, "allan", None) for r in rests]),
        accel_residual_std,
        accel_samples,
    )
    out = {"rate_hz": float(rate_hz), "definition": DEFINITION}
    if accel is not None:
        out["accelerometer"] = accel
    if gyro_residual_rms is not None:
        with_gyro = [r for r in rests if getattr(r, "gyro_noise_std_radps", None) is not None]
        gyro = sensor_block(
            "gyroscope",
            rate_hz,
            [r.gyro_noise_std_radps for r in with_gyro],
            [r.samples for r in with_gyro],
            AllanSums.combined([getattr(r, "gyro_allan", None) for r in with_gyro]),
            gyro_residual_rms,
            gyro_samples,
        )
        if gyro is not None:
            out["gyroscope"] = gyro
    return out if len(out) > 2 else None


def kalibr_values(calibration: Mapping) -> dict[str, tuple[float, str] | None]:
    """Kalibr's four noise keys of a calibration: (largest axis's value, its note), or None.

    The largest axis, as Kalibr takes one number per sensor (allan_variance_ros does
    the same: "use worst value").
    """
    block = calibration.get("imu_noise") or {}
    out: dict[str, tuple[float, str] | None] = {}
    for key, (kind, what) in KALIBR_KEYS.items():
        sensor = block.get(kind)
        _, density_unit, walk_unit = SENSORS[kind]
        field = f"{what}_{density_unit if what == 'noise_density' else walk_unit}"
        values = None if not sensor else sensor.get(field)
        if not values or any(v is None for v in values):
            out[key] = None
            continue
        value = float(max(values))
        if what == "noise_density":
            note = _density_note(sensor, density_unit)
        else:
            bound = any(sensor.get("random_walk_is_upper_bound") or [True])
            note = (
                "UPPER BOUND (min over tau of sigma(tau)*sqrt(3/tau) of the rests' Allan "
                "deviation; the rests are too short to show the random walk): conservative"
                if bound
                else "from the +1/2 slope of the rests' Allan deviation"
            )
        out[key] = (value, note)
    return out


def _density_note(sensor: Mapping, unit: str) -> str:
    """Where a noise density comes from, and how the Allan deviation checks it."""
    source = sensor.get("source")
    rel = sensor.get("white_std_rel_std")
    where = (
        f"sigma per sample of {sensor.get('samples')} samples at rest / sqrt(rate)"
        if source == "rests"
        else "sigma of the fit's residual (no rests) / sqrt(rate): an upper side"
    )
    if rel:
        where += f", +-{100 * rel:.1g} %"
    z = sensor.get("allan_z")
    allan = sensor.get(f"allan_density_{unit}")
    if z and allan and sensor.get("allan_rel_std") and None not in z and None not in allan:
        worst = max(abs(v) for v in z)
        where += (
            f"; the check, the Allan deviation at tau = 1 s: {min(allan):.3g} to "
            f"{max(allan):.3g} per axis (+-{100 * sensor['allan_rel_std']:.2g} % each), at "
            f"most {worst:.2g} of its sigma from these"
        )
    return where


def pooled_imu_noise(blocks: Sequence[Mapping | None]) -> dict | None:
    """One ``imu_noise`` from several sessions' (of the most common rate).

    The per-sample σ pool as variances weighted by samples (sessions without a
    count weigh as one); the Allan read-outs and random walks are the sessions'
    largest (the walk's bound holds for each; the largest is the one that holds
    for all).
    """
    rate, same = of_the_common_rate(blocks)
    if not same:
        return None
    out: dict = {"rate_hz": rate, "definition": DEFINITION}
    for kind, (sample, density_unit, walk_unit) in SENSORS.items():
        parts = [b[kind] for b in same if b.get(kind)]
        if not parts:
            continue
        weights = np.array([max(p.get("samples") or 1, 2) - 1 for p in parts], dtype=float)
        var = np.array([np.asarray(p[f"white_std_{sample}"], float) ** 2 for p in parts])
        std = np.sqrt(weights @ var / weights.sum())
        samples = int(sum(p.get("samples") or 0 for p in parts))
        walks = [p.get(f"random_walk_{walk_unit}") for p in parts]
        walks = [w for w in walks if w and all(v is not None for v in w)]
        sources = sorted({str(p.get("source")) for p in parts})
        out[kind] = {
            "source": sources[0] if len(sources) == 1 else "+".join(sources),
            "samples": samples,
            f"white_std_{sample}": _vec(std),
            "white_std_rel_std": _num(1 / math.sqrt(2 * (samples - 1)) if samples > 1 else None),
            f"noise_density_{density_unit}": _vec(std / math.sqrt(rate)),
            f"allan_density_{density_unit}": None,
            "allan_rel_std": None,
            "allan_z": None,
            f"random_walk_{walk_unit}": _vec(np.max(walks, axis=0)) if walks else None,
            "random_walk_is_upper_bound": (
                [
                    any(bool((p.get("random_walk_is_upper_bound") or [True] * 3)[k]) for p in parts)
                    for k in range(3)
                ]
                if walks
                else None
            ),
            "sessions": len(parts),
        }
    return out if len(out) > 2 else None
