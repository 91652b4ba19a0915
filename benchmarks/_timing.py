"""Shared by the benchmark scripts: repeated timings and their summary line."""

from __future__ import annotations

import statistics
import time


def times(fn, repeats: int, clock=time.perf_counter) -> list[float]:
    """Run ``fn`` once to warm up, then ``repeats`` times; seconds per run."""
    fn()  # warm-up (imports, caches)
    out = []
    for _ in range(repeats):
        t0 = clock()
        fn()
        out.append(clock() - t0)
    return out


def fmt(ts: list[float]) -> str:
    """Median and inter-quartile range in ms."""
    q = statistics.quantiles(ts, n=4) if len(ts) >= 4 else [min(ts), statistics.median(ts), max(ts)]
    med = 1e3 * statistics.median(ts)
    return f"median {med:8.1f} ms   (IQR {1e3 * q[0]:.1f}–{1e3 * q[2]:.1f} ms, n={len(ts)})"
