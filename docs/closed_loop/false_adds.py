"""Count false additions of the closed loop and of the pooled sensor tests on clean data.

* closed loop: 200 clean Table I recordings, white and 20 Hz low-pass noise (σ_n = 0.08);
* pooled tests: 200 clean batches of 10 Table II recordings (one sensor, one mounting).

Prints the counts and rates (the issues ask for ≤ 2 %); the `slow` tests assert the same.
Run:  python docs/closed_loop/false_adds.py [--seeds 200]
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from threadpoolctl import threadpool_limits

from wheelcal.closedloop.loop import ClosedLoop
from wheelcal.closedloop.score import pooled_score_tests
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.model.effects import intrinsic_candidates
from wheelcal.simulate import NoiseSpec, simulate, table1, table2


def loop_adds(args) -> int:
    bandwidth, seed = args
    with threadpool_limits(1):
        rec = simulate(
            table1(NoiseSpec(0.08, bandwidth_hz=bandwidth)), np.random.default_rng(seed)
        ).recording
        return len(ClosedLoop().run(rec).steps)


def pooled_adds(seed: int) -> int:
    with threadpool_limits(1):
        fits, recs = [], []
        for i in range(10):
            rng = np.random.default_rng([seed, i])
            rec = simulate(table2(rng=rng), rng).recording
            recs.append(rec)
            fits.append(JointFit().fit(rec))
        tests = pooled_score_tests(fits, recs, intrinsic_candidates())
        return sum(t.identifiable and t.p_corrected < 0.01 for t in tests)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=200)
    n = ap.parse_args().seeds
    with ProcessPoolExecutor(2) as pool:
        for bandwidth in (None, 20.0):
            adds = list(pool.map(loop_adds, [(bandwidth, s) for s in range(n)], chunksize=4))
            hits = sum(a > 0 for a in adds)
            kind = "white" if bandwidth is None else f"{bandwidth:g} Hz low-pass"
            print(
                f"closed loop, {kind}: effect added in {hits}/{n} clean recordings ({100 * hits / n:.1f} %)"
            )
        adds = list(pool.map(pooled_adds, range(5000, 5000 + n), chunksize=2))
        hits = sum(a > 0 for a in adds)
        print(
            f"pooled sensor tests: effect found in {hits}/{n} clean batches of 10 ({100 * hits / n:.1f} %)"
        )


if __name__ == "__main__":
    main()
