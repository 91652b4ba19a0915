"""No false refusals: the 200 random realistic sessions and the paper's presets, counted.

Each random setup (the accuracy tests' generator: tilt 10°–85°, either spin
direction, 60–120 s, 100–1000 Hz, gains ±5 %, offsets ±0.5 m/s²) is simulated
as a whole session (rest, push, spin, brake, rest) and calibrated through the
gates.  Printed: refusals (with their gate), warnings by kind, the rest
check's false alarms against its family-wise α = 1 %, and the worst error in
units of the CRLB at the truth.

    python docs/trust/false_refusals.py [--setups 200]
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from truth_bound import sigmas_off
from wheelcal.recording import CalibrationRefused
from wheelcal.session.fit import SessionFit
from wheelcal.simulate import random_setup, simulate_session


def kind(warning: str) -> str:
    if "left unexplained" in warning:
        return "unexplained residual"
    if warning.startswith("at rest"):
        return "rest check"
    if "gains average" in warning:
        return "mean gain (radius)"
    if "sensitivity tolerance" in warning:
        return "gain tolerance"
    if "zero-g tolerance" in warning:
        return "offset tolerance"
    if "poorly determined" in warning:
        return "poorly determined"
    return "other: " + warning[:50]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--setups", type=int, default=200)
    args = ap.parse_args()
    refused, kinds, worst, rest_alarm = [], Counter(), [], 0
    with threadpool_limits(1):
        for seed in range(args.setups):
            rng = np.random.default_rng(seed)
            session = simulate_session(random_setup(rng), rng)
            try:
                result = SessionFit().run(session.recording).result
            except CalibrationRefused as exc:
                refused.append((seed, exc.gate, exc.reason[:80]))
                continue
            seen = {kind(w) for w in result.warnings}
            kinds.update(seen)
            rest_alarm += "rest check" in seen
            worst.append(max(sigmas_off(session, result).values()))
    n = args.setups
    print(f"random realistic sessions: {n}")
    print(f"refused: {len(refused)}" + "".join(f"\n  seed {s}: {g} — {r}" for s, g, r in refused))
    print("sessions with a warning, by kind:", dict(kinds) or "none")
    print(
        f"rest-check false alarms: {rest_alarm}/{n} (family-wise α = 1 % → expected {0.01 * n:.0f})"
    )
    worst = np.array(worst)
    print(
        f"worst gain/offset error per session (σ_CRLB): median {np.median(worst):.2f}, "
        f"max {worst.max():.2f}; > 5: {int(np.sum(worst > 5))}"
    )


if __name__ == "__main__":
    main()
