"""Peak memory and time of reading CSV logs, sound and hostile (issue 40, CSV part).

Generates once, in a temporary directory (or ``--dir``, reused when the files are
there):

* ``sound.csv``: 1,000,000 rows ``Time (s),Accelerometer X (g),…`` (≈ 37 MB, the
  size of the issue's "sound 1 M-row CSV"), a spinning sensor at 200 Hz;
* ``xsens.csv``: 1,000,000 rows in the Xsens DOT export's layout (Euler, Acc, Gyr;
  ≈ 190 MB);
* hostile files: ``sparse.csv`` (a header, three rows, then a 2 GB hole: sparse, no
  disk), ``hole.csv`` (2 GB of nothing but a hole), ``wide.csv`` (10⁶ columns),
  ``huge.csv`` (3 GiB, sparse), ``endless.csv`` (64 MB without a line end);
  ``/dev/zero`` is read as it is.

Then runs each case in a fresh subprocess and prints its peak resident set size
(``ru_maxrss`` of the child via ``resource.getrusage(RUSAGE_CHILDREN)``, measured by a
tiny launcher process so that every figure is that one child's) and its wall time:

* baselines, in the same run: the interpreter with the modules a CSV read imports
  (``imports``), and the MCAP read of the same samples (``read mcap``, the file
  ``convert`` wrote);
* ``read csv``: :func:`wheelcal.io.read_recording` on the CSV (what ``calibrate`` does);
* ``convert``: ``wheelcal convert FILE OUT.mcap``;
* the hostile files through both.

Columns: peak MiB; above the ``imports`` baseline; that over the file size, and the
whole peak over it (``abs``); the peak over the MCAP read's (same samples); seconds.  The targets (issue 40): every hostile
case ≤ 1 GiB, a sound 1 M-row CSV ≤ 3× its size (what reading it adds to the
interpreter and its imports, 70 MB before any file), no case over 60 s — checked at
the end.  ``--src DIR`` runs the children on another source tree (``DIR/src``), e.g. an
older commit's, for a before/after in the same conditions.

Run: ``python benchmarks/bench_csv_memory.py [--dir DIR] [--src TREE] [--only sound,…]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROWS = 1_000_000
RATE_HZ = 200.0
GIB = 1 << 30

_LAUNCH = """
import resource, subprocess, sys
done = subprocess.run(sys.argv[1:], capture_output=True, text=True, timeout=300)
err = (done.stderr.strip().splitlines() or [""])[-1]
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, done.returncode, err)
"""
_IMPORTS = "import numpy, pyarrow.csv, pyarrow.compute, wheelcal.io, wheelcal.cli.main"
_READ = (
    "import sys\n"
    "from wheelcal.io import read_recording\n"
    "rec = read_recording(sys.argv[1], info_overrides={'radius_m': 0.28})\n"
    "print(rec.samples)\n"
)


def _spin(rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (s), accelerometer (g) and gyro (deg/s) of a sensor turning on a tilted wheel."""
    rng = np.random.default_rng(1)
    t = np.arange(rows) / RATE_HZ
    angle = 12.0 * t
    accel = np.stack([0.5 * np.cos(angle), 0.5 * np.sin(angle), np.full(rows, 0.866)], axis=1)
    accel += rng.normal(0.0, 0.002, accel.shape)
    gyro = np.tile([0.0, 0.0, np.degrees(12.0)], (rows, 1)) + rng.normal(0.0, 0.05, accel.shape)
    return t, accel, gyro


def generate(directory: Path) -> dict[str, Path]:
    """The benchmark's files in ``directory`` (written if absent)."""
    paths = {name: directory / f"{name}.csv" for name in ("sound", "xsens")}
    t, accel, gyro = _spin(ROWS)
    if not paths["sound"].exists():
        with open(paths["sound"], "w") as out:
            axes = ",".join(f"Accelerometer {a} (g)" for a in "XYZ")
            out.write(f"Time (s),{axes}\n")
            np.savetxt(out, np.column_stack([t, accel]), fmt="%.6f", delimiter=",")
    if not paths["xsens"].exists():
        ticks = (715_432_688 + np.rint(t * 1e6).astype(np.int64)) % 2**32
        euler = np.tile([-84.25903, -42.10929, -47.84157], (ROWS, 1))
        table = np.column_stack([np.arange(ROWS) % 65536, ticks, euler, accel * 9.80665, gyro])
        with open(paths["xsens"], "w") as out:
            out.write("sep=,\n")
            out.write(
                "PacketCounter,SampleTimeFine,Euler_X,Euler_Y,Euler_Z,Acc_X,Acc_Y,Acc_Z,"
                "Gyr_X,Gyr_Y,Gyr_Z,\n"
            )
            fmt = ["%d", "%d"] + ["%.15g"] * 9
            np.savetxt(out, table, fmt=fmt, delimiter=", ", newline=", \n")
    header = "t,ax,ay,az\n0,0.1,0.2,9.8\n0.005,0.1,0.2,9.8\n0.01,0.1,0.2,9.8\n"
    hostile = {
        "sparse": (header, 2_000_000_000),
        "hole": ("", 2_000_000_000),
        "huge": (header, 3 * GIB),
    }
    for name, (text, size) in hostile.items():
        path = paths.setdefault(name, directory / f"{name}.csv")
        if not path.exists():
            path.write_text(text)
            os.truncate(path, size)  # a hole: no disk
    paths["wide"] = directory / "wide.csv"
    if not paths["wide"].exists():
        paths["wide"].write_text(
            "t," + ",".join(f"c{i}" for i in range(10**6)) + "\n0," + "1," * 999_999 + "1\n"
        )
    paths["endless"] = directory / "endless.csv"
    if not paths["endless"].exists():
        paths["endless"].write_bytes(b"t,ax,ay,az\n" + b"1" * (64 << 20))
    return paths


def run(argv: list[str], env: dict[str, str]) -> tuple[int, int, float, str]:
    """(peak RSS in bytes, exit code, wall seconds, last stderr line) of ``argv``."""
    t0 = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-c", _LAUNCH, *argv], capture_output=True, text=True, env=env
    )
    elapsed = time.perf_counter() - t0
    kib, rc, *err = out.stdout.split(" ", 2) if out.stdout else ("0", "-1", out.stderr)
    return int(kib) * 1024, int(rc), elapsed, " ".join(err).strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", type=Path, help="where to keep the generated files")
    parser.add_argument("--src", type=Path, help="run the children on TREE/src (another commit)")
    parser.add_argument("--only", help="these files only, comma-separated (e.g. sound,wide)")
    args = parser.parse_args()
    env = dict(os.environ)
    if args.src:
        env["PYTHONPATH"] = str(args.src.resolve() / "src")
    with tempfile.TemporaryDirectory() as tmp:
        directory = args.dir or Path(tmp)
        directory.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        paths = generate(directory)
        print(f"files in {directory} ({time.perf_counter() - t0:.1f} s)")
        cli = [sys.executable, "-m", "wheelcal.cli.main"]

        def read(path) -> list[str]:
            return [sys.executable, "-c", _READ, str(path)]

        def convert(path, name: str) -> list[str]:
            out = directory / f"{name}.mcap"
            out.unlink(missing_ok=True)
            return [*cli, "convert", str(path), str(out)]

        base, *_ = run([sys.executable, "-c", _IMPORTS], env)
        print(f"baseline: imports ({_IMPORTS}): {base / 2**20:.1f} MiB")
        cases = []
        for name in ("sound", "xsens"):
            cases += [
                (name, "convert", convert(paths[name], name), False),
                (name, "read mcap", read(directory / f"{name}.mcap"), False),
                (name, "read csv", read(paths[name]), False),
            ]
        for name in ("sparse", "hole", "wide", "huge", "endless"):
            cases += [
                (name, "convert", convert(paths[name], name), True),
                (name, "read csv", read(paths[name]), True),
            ]
        cases.append(("/dev/zero", "convert", convert("/dev/zero", "zero"), True))
        if args.only:
            cases = [case for case in cases if case[0] in args.only.split(",")]
        print(
            f"{'file':10s} {'what':10s} {'size MB':>9s} {'exit':>4s} {'peak MiB':>9s} "
            f"{'+imports':>9s} {'/ size':>7s} {'(abs)':>7s} {'/ mcap':>7s} {'s':>6s}  message"
        )
        mcap_peak: dict[str, int] = {}
        failures = []
        for name, what, argv, hostile in cases:
            path = paths.get(name, Path(name))
            size = path.stat().st_size if path.is_file() else 0
            peak, rc, elapsed, err = run(argv, env)
            if what == "read mcap":
                mcap_peak[name] = peak
            above = peak - base
            per_size = f"{above / size:7.2f}" if size and not hostile else ""
            absolute = f"{peak / size:7.2f}" if size and not hostile else ""
            per_mcap = f"{peak / mcap_peak[name]:7.2f}" if name in mcap_peak else ""
            message = err[:90] if rc else ""
            print(
                f"{name:10s} {what:10s} {size / 1e6:9.1f} {rc:4d} {peak / 2**20:9.1f} "
                f"{above / 2**20:9.1f} {per_size:>7s} {absolute:>7s} {per_mcap:>7s} {elapsed:6.2f}"
                f"  {message}"
            )
            if elapsed > 60:
                failures.append(f"{name} {what}: {elapsed:.0f} s > 60 s")
            if hostile and peak > GIB:
                failures.append(f"{name} {what}: {peak / 2**20:.0f} MiB > 1 GiB")
            if name == "sound" and what != "read mcap" and above > 3 * size:
                failures.append(f"sound {what}: {above / size:.2f}× the file size > 3×")
            if hostile and rc == 0:
                failures.append(f"{name} {what}: accepted")
        print("targets: " + ("all met" if not failures else "MISSED: " + "; ".join(failures)))


if __name__ == "__main__":
    main()
