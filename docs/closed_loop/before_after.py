"""Regenerate the before/after table of the closed loop (docs/guide/closed-loop.md).

For each effect at the size the issue names (undeclared in the data), one Table I
recording (σ_n = 0.08 m/s², 90 s at 200 Hz; gain drift at 0.02 m/s², see below)
is calibrated with the paper's model and then diagnosed.  Printed per effect:
what the loop found (χ², corrected p), the residual RMS before → after, and the
worst sensor-parameter error before → after in units of σ_CRLB evaluated at the
simulator's truth (true sensor, bench, spin law and effects, true noise) for the
model fitted: the paper's model before, the model with the found effects after
(``tests/test_closed_loop.py::truth_bound_of``).  Never the fit's own σ.

Run:  python docs/closed_loop/before_after.py
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from test_closed_loop import truth_bound_of
from wheelcal.closedloop.loop import ClosedLoop
from wheelcal.model import ParameterLayout
from wheelcal.model.effects import GainDrift, OffsetWarmup, QuadraticNonlinearity
from wheelcal.simulate import NoiseSpec, simulate, table1
from wheelcal.simulate.motion import DragSpin, ImbalancedSpin

SENSOR = ("gain_x", "gain_y", "gain_z", "offset_x_mps2", "offset_y_mps2", "offset_z_mps2")


def cases():
    s = table1()
    warm = list(np.array([0.08, -0.05, 0.1]) * np.exp(-45 / 25))
    yield (
        "spin-down, quadratic drag 11 → 5.5 rad/s",
        dataclasses.replace(s, motion=DragSpin(11.0, 5.5, 90.0, 0.3)),
    )
    yield (
        "imbalance torque 0.15 rad/s²",
        dataclasses.replace(
            s, motion=ImbalancedSpin(s.truth.spin, 0.15 * np.cos(0.7), 0.15 * np.sin(0.7))
        ),
    )
    yield (
        "nonlinearity 1e-3 /(m/s²) on z",
        dataclasses.replace(
            s,
            truth=s.truth.with_changes(effects={"nonlinearity_z": [1e-3]}),
            effects=(QuadraticNonlinearity(2),),
        ),
    )
    yield (
        "offset warm-up 0.05–0.1 m/s², τ = 25 s",
        dataclasses.replace(
            s,
            truth=s.truth.with_changes(effects={"offset_warmup": warm}),
            effects=(OffsetWarmup(25.0),),
        ),
    )
    yield (
        "gain drift 1e-3 over 90 s (σ_n 0.02)",
        dataclasses.replace(
            s,
            truth=s.truth.with_changes(effects={"gain_drift": [1e-3 / 90, -1e-3 / 90, 1e-3 / 90]}),
            effects=(GainDrift(),),
            noise=NoiseSpec(0.02),
        ),
    )
    yield "none (clean recording)", s


def main() -> None:
    print(
        "| effect in the data | found (χ², p corrected) | residual RMS before → after (m/s²) | worst sensor error before → after (σ_CRLB at the truth) |"
    )
    print("|---|---|---|---|")
    with threadpool_limits(1):
        for label, scenario in cases():
            rec = simulate(scenario, np.random.default_rng(31)).recording
            d = ClosedLoop().run(rec)
            err = {}
            for which, fit, layout in (
                ("base", d.base, ParameterLayout()),
                ("final", d.final, d.final.layout),
            ):
                bound = truth_bound_of(scenario, layout)
                truth = dict(zip(bound.names, bound.values, strict=True))
                err[which] = max(abs(fit.value_of(n) - truth[n]) / bound.std_of(n) for n in SENSOR)
            found = (
                "; ".join(
                    f"`{s.test.effect.name}` ({s.test.statistic:.0f}, {s.test.p_corrected:.0e})"
                    for s in d.steps
                )
                or "nothing"
            )
            rms = lambda r: "/".join(f"{x:.3f}" for x in r.residual_rms_mps2)  # noqa: E731
            print(
                f"| {label} | {found} | {rms(d.base)} → {rms(d.final)} | {err['base']:.1f} → {err['final']:.1f} |"
            )


if __name__ == "__main__":
    main()
