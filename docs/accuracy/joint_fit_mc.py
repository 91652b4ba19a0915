"""Print the joint fit's Monte Carlo figures against the CRLB (the `slow` tests assert them).

Table I truth, 100 seeds per configuration (σ_n = 0.08 and 0.2 m/s², white and 20 Hz
low-pass noise): per group, the worst |bias|/σ_CRLB, the mean and worst std/σ_CRLB,
and the mean reported σ / observed spread.  Then 200 random setups: the worst
|estimate − truth|/σ_CRLB of each.

Run:  python docs/accuracy/joint_fit_mc.py [--seeds 100] [--setups 200]
"""

from __future__ import annotations

import argparse

import numpy as np

from wheelcal.estimate.joint.fit import JointFit
from wheelcal.simulate import NoiseSpec, random_setup, simulate, table1
from wheelcal.study import PARAMETER_GROUPS, group_of, monte_carlo
from wheelcal.study.montecarlo import scenario_bound


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--setups", type=int, default=200)
    args = ap.parse_args()
    for bandwidth in (None, 20.0):
        for sigma in (0.08, 0.2):
            m = monte_carlo(
                table1(NoiseSpec(sigma, bandwidth_hz=bandwidth)), JointFit(), range(args.seeds)
            )
            kind = "white" if bandwidth is None else "20 Hz low-pass"
            print(f"σ_n = {sigma} m/s², {kind}, {m.runs} runs ({m.failures} failed)")
            groups = np.array([group_of(n) for n in m.names])
            for g in PARAMETER_GROUPS:
                sel = groups == g
                print(
                    f"  {g:13s} max|bias|/σ {np.abs(m.bias_over_crlb[sel]).max():.2f}  "
                    f"std/σ mean {m.std_over_crlb[sel].mean():.2f} max {m.std_over_crlb[sel].max():.2f}  "
                    f"reported/observed {m.reported_over_observed[sel].mean():.2f}"
                )
    worst = []
    for seed in range(args.setups):
        rng = np.random.default_rng(seed)
        scenario = random_setup(rng)
        result = JointFit().fit(simulate(scenario, rng).recording)
        bound = scenario_bound(scenario, result.layout)
        d = result.values - bound.values
        d[0] = (d[0] + np.pi) % (2 * np.pi) - np.pi
        worst.append(float(np.max(np.abs(d) / bound.std)))
    worst = np.array(worst)
    print(
        f"{args.setups} random setups: worst |error|/σ_CRLB per setup — median {np.median(worst):.2f}, "
        f"95th percentile {np.percentile(worst, 95):.2f}, max {worst.max():.2f}; beyond 5σ: {int(np.sum(worst >= 5))}"
    )


if __name__ == "__main__":
    main()
