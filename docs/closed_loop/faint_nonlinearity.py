"""Print the figures of the sensor-level closure's example, a faint nonlinearity (docs/guide/closed-loop.md).

Ten Table II recordings of one sensor, mounted so that the x axis sees a
4·10⁻⁴ /(m/s²) quadratic nonlinearity only faintly, go through the batch runner
with the closure on (``tests/test_closure.py::faint_nonlinearity_run``, which the
test of the same name asserts on).  Printed: each recording's noncentrality of the
nonlinearity, (k/σ_CRLB(k))² at the truth; each single recording's offset_x error
(paper's model) in σ_CRLB at the truth; the pooled test's χ² and p; the joint
sensor fit's offsets in σ_CRLB of the joint model at the truth.

Run:  python docs/closed_loop/faint_nonlinearity.py   (about 10 s; writes only to a temp dir)
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from test_closure import faint_nonlinearity_run


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp, threadpool_limits(1):
        run = faint_nonlinearity_run(Path(tmp))
    lam = np.array(run["noncentrality"])
    z = np.abs(run["single_z"])
    test = run["tests"]["nonlinearity_x"]
    print(f"noncentrality per recording: {lam.min():.1f}–{lam.max():.1f} (mean {lam.mean():.1f})")
    print(
        f"single recordings' |offset_x error| / σ_CRLB: {z.min():.1f}–{z.max():.1f} "
        f"(mean {z.mean():.1f}; {int(np.sum(z > 4))} of {z.size} above 4)"
    )
    print(
        f"pooled test nonlinearity_x: χ² = {test['statistic']:.1f} on {test['dof']} dof, "
        f"p = {test['p_value']:.1e}, corrected p = {test['p_corrected']:.1e}"
    )
    joint = ", ".join(f"{k} {v:+.2f}" for k, v in run["joint_z"].items())
    print(f"joint sensor fit's offsets, (estimate − truth) / σ_CRLB: {joint}")


if __name__ == "__main__":
    main()
