"""Peak memory of reading and of ``wheelcal calibrate`` per sample (issue 16, item 8).

Generates once, in a temporary directory (or ``--dir``, reused when the files
are there), two ROS 2 Imu MCAP recordings written by
:func:`wheelcal.io.write_recording` from :func:`wheelcal.simulate.simulate`:

* ``long``: one hour at 200 Hz (720,000 samples, table II bench);
* ``fast``: 29 s at 100 kHz (2.9 M samples);
* ``small``: 90 s at 200 Hz (18,001 samples): what a calibration costs whatever its size
  (modules imported on the way, the fit's fixed buffers), so that the large files' growth
  per sample can be told from it (the ``marginal`` column).

Then measures, each in a fresh subprocess, the peak resident set size
(``ru_maxrss`` of the child, via ``resource.getrusage(RUSAGE_CHILDREN)`` —
measured by a tiny launcher process so that every figure is that one child's):

* (a) baseline: ``import wheelcal`` (and numpy, the reader and the CLI);
* (b) reading only: :func:`wheelcal.io.read_recording`;
* (c) the whole ``wheelcal calibrate FILE --out DIR``.

and prints MB, bytes per sample above the baseline, and the marginal bytes per sample
(above the ``small`` file's peak, per extra sample).  The target (issue 16)
is ≤ 100 B per sample for (c); the samples themselves are 24 B (float64 × 3).
Run: ``python benchmarks/bench_memory.py [--dir DIR] [--only long|fast]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

FILES = {"small": (90.0, 200.0), "long": (3600.0, 200.0), "fast": (29.0, 100_000.0)}

_LAUNCH = """
import resource, subprocess, sys
rc = subprocess.run(sys.argv[1:]).returncode
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, rc)
"""

_BASELINE = "import numpy, wheelcal, wheelcal.io, wheelcal.cli.main"
_READ = (
    "import sys\n"
    "from wheelcal.io import read_recording\n"
    "rec = read_recording(sys.argv[1])\n"
    "print(rec.samples, file=sys.stderr)\n"
)


def generate(directory: Path, name: str) -> Path:
    """The recording ``name`` (see FILES) in ``directory``, written if absent."""
    from wheelcal.io import write_recording
    from wheelcal.recording import SessionInfo
    from wheelcal.simulate import Scenario, simulate, table2

    path = directory / f"{name}.mcap"
    if path.exists():
        return path
    duration_s, rate_hz = FILES[name]
    base = table2(rng=np.random.default_rng(1))
    truth = base.truth
    if duration_s > 600:
        # An hour of free spin: a slow, steady decay (a hand spin's cubic would run away).
        from dataclasses import replace

        from wheelcal.model.parameters import SpinParams

        truth = replace(truth, spin=SpinParams(theta0_rad=0.0, omega_radps=[12.0, -1e-3]))
    scenario = Scenario(
        truth=truth,
        duration_s=duration_s,
        rate_hz=rate_hz,
        info=SessionInfo(radius_m=0.28),
    )
    t0 = time.perf_counter()
    rec = simulate(scenario, np.random.default_rng(2)).recording
    write_recording(rec, path)
    print(
        f"generated {path.name}: {rec.samples:,} samples, "
        f"{path.stat().st_size / 1e6:.1f} MB, {time.perf_counter() - t0:.1f} s"
    )
    return path


def peak_rss_bytes(argv: list[str]) -> tuple[int, int]:
    """(peak RSS in bytes, exit code) of the command ``argv``, run in its own process."""
    out = subprocess.run(
        [sys.executable, "-c", _LAUNCH, *argv],
        capture_output=True,
        text=True,
        check=True,
    )
    kib, rc = out.stdout.split()[-2:]
    return int(kib) * 1024, int(rc)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", type=Path, help="where to keep the generated files")
    parser.add_argument("--only", choices=sorted(FILES), help="one recording only")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        directory = args.dir or Path(tmp)
        directory.mkdir(parents=True, exist_ok=True)
        names = [args.only] if args.only else list(FILES)
        paths = {name: generate(directory, name) for name in names}
        base, _ = peak_rss_bytes([sys.executable, "-c", _BASELINE])
        print(f"baseline (import wheelcal): {base / 1e6:7.1f} MB")
        print(
            f"{'file':6s} {'samples':>10s} {'what':10s} {'peak MB':>9s} {'B/sample':>9s}"
            f" {'marginal':>9s}"
        )
        small: dict[str, tuple[int, int]] = {}
        for name, path in paths.items():
            duration_s, rate_hz = FILES[name]
            samples = round(duration_s * rate_hz) + 1
            runs = {
                "read": [sys.executable, "-c", _READ, str(path)],
                "calibrate": [
                    sys.executable,
                    "-m",
                    "wheelcal.cli.main",
                    "calibrate",
                    str(path),
                    "--out",
                    str(directory / f"out-{name}"),
                ],
            }
            for what, argv in runs.items():
                peak, rc = peak_rss_bytes(argv)
                status = "" if rc == 0 else f"   (exit {rc})"
                if name == "small":
                    small[what] = (peak, samples)
                marginal = ""
                if what in small and name != "small":
                    p0, n0 = small[what]
                    marginal = f"{(peak - p0) / (samples - n0):9.1f}"
                print(
                    f"{name:6s} {samples:10,d} {what:10s} {peak / 1e6:9.1f} "
                    f"{(peak - base) / samples:9.1f} {marginal:>9s}{status}"
                )


if __name__ == "__main__":
    main()
