"""The gyroscope tables of docs/guide/gyroscope-and-rolling.md: what the flexible wheel angle and an imbalance cost.

Analytic Cramér–Rao bounds at the truth (σ of gains, offsets and tilt), for
the paper's Table I and Table II setups (90 s, 200 Hz, σ_n = 0.08 m/s², an
MPU-9250-class gyro):

1. gyro + spline wheel angle (knots 8, 2, 0.5 s) over the accelerometer-only cubic;
2. an imbalance of 0.4 rad/s²: accelerometer only with the imbalance effect, and
   with the gyro, each over the accelerometer-only bound without imbalance.

    python docs/gyro/tables.py
"""

from __future__ import annotations

import numpy as np
from threadpoolctl import threadpool_limits

from wheelcal.estimate.joint.crlb import cramer_rao_bound, cramer_rao_bound_with_gyro
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.model import ParameterLayout
from wheelcal.model.effects import GyroReading, Imbalance, SpinSpline
from wheelcal.simulate import table1, table2
from wheelcal.simulate.gyro import GyroSpec

NAMES = [f"gain_{a}" for a in "xyz"] + [f"offset_{a}_mps2" for a in "xyz"] + ["tilt_deg"]
SPEC = GyroSpec()


def ratios(a, b):
    values = [a.std_of(n) / b.std_of(n) for n in NAMES]
    return f"{min(values):.2f}–{max(values):.2f}"


def main() -> None:
    print(
        "| setup | gyro + spline (8 s / 2 s / 0.5 s knots) ÷ cubic | imbalance 0.4 rad/s², accelerometer only | imbalance, with the gyro |"
    )
    print("|---|---|---|---|")
    with threadpool_limits(1):
        for name, scenario in (
            ("Table I", table1()),
            ("Table II", table2(rng=np.random.default_rng(3))),
        ):
            t = scenario.centred_times_s()
            rate = scenario.rate_hz
            noise = NoiseModel.from_ar(
                scenario.noise.ar_polynomial(rate), scenario.noise.innovation_std(rate)
            )
            gyro_noise = NoiseModel.white(SPEC.noise_std_radps(rate))
            rotation = scenario.truth.bench.misalignment.matrix
            k, u = SPEC.wheel_axis_response(rotation)
            g_sens = SPEC.g_sensitivity_radps_per_mps2
            bias = np.asarray(SPEC.bias_radps) + g_sens @ rotation[:, 2] * 9.80665 * np.cos(
                scenario.truth.bench.tilt_rad
            )
            reading = np.concatenate(
                [k * u, bias, g_sens @ rotation[:, 0], g_sens @ rotation[:, 1]]
            )
            base = cramer_rao_bound(scenario.truth, t, noise, ParameterLayout())
            flexible = []
            for spacing in (8.0, 2.0, 0.5):
                spline = SpinSpline(t[0], t[-1], spacing)
                truth = scenario.truth.with_changes(
                    effects={"gyro": reading, spline.name: np.zeros(spline.size)}
                )
                bound = cramer_rao_bound_with_gyro(
                    truth, t, noise, ParameterLayout(effects=(spline, GyroReading())), gyro_noise
                )
                flexible.append(ratios(bound, base))
            imbalance = np.array([0.4 * np.cos(0.7), 0.4 * np.sin(0.7)])
            acc = cramer_rao_bound(
                scenario.truth.with_changes(effects={"imbalance": imbalance}),
                t,
                noise,
                ParameterLayout(effects=(Imbalance(),)),
            )
            gyro = cramer_rao_bound_with_gyro(
                scenario.truth.with_changes(effects={"imbalance": imbalance, "gyro": reading}),
                t,
                noise,
                ParameterLayout(effects=(Imbalance(), GyroReading())),
                gyro_noise,
            )
            print(
                f"| {name} | {' / '.join(flexible)} | {ratios(acc, base)} | {ratios(gyro, base)} |"
            )


if __name__ == "__main__":
    main()
