"""What the pooled gyro fit (the gyroscope's full matrix) adds to a batch.

One IMU in three mountings (the wheel axis near the sensor's x, y and z), three
whole sessions each (90 s at 200 Hz, rest, push, spin, brake, rest; ROS 2 MCAP),
generated once.  Then, in this process and alternating round by round:

* the default ``wheelcal batch`` of the nine (``--workers`` local workers, default 1:
  in this process, so that every CPU second is counted; no Rerun output), which
  writes the sensor's pooled file with its ``gyro`` block;
* the same batch with the pooled gyro fit switched off (the sensor file without
  its ``gyro`` block: the baseline, what a batch cost before);

and the pooled gyro fit alone (:func:`wheelcal.calibration.gyro_json.gyro_block` on
the nine sessions' calibrations).  Prints the medians of the wall time and of the
CPU seconds (this process and its workers: steadier than the wall time on a
shared machine), and their ratios; target ≤ 1.05.

Run:  python benchmarks/bench_gyro_matrix.py [--rounds 9] [--workers 1]

Measured (2 shared cores, load ≈ 4): CPU per batch 2.28 s with the pooled gyro fit,
2.31 s without (ratio 1.00); wall time ratio 1.03 (the load's noise); the pooled fit
alone 4–8 ms, 0.2 % of the batch.
"""

from __future__ import annotations

import argparse
import json
import resource
import shutil
import statistics
import tempfile
from pathlib import Path

import numpy as np

from _timing import fmt, interleaved_times, times


def _recordings(folder: Path) -> None:
    from wheelcal.io import write_recording
    from wheelcal.simulate.gyro import GyroSpec
    from wheelcal.simulate.mountings import imu_sessions

    gyro = GyroSpec.device(np.random.default_rng(38))
    folder.mkdir(parents=True, exist_ok=True)
    for i, session in enumerate(imu_sessions(np.random.default_rng(39), gyro)):
        write_recording(session.recording, folder / f"s{i}.mcap")


def _batch(root: Path, inputs: Path, workers: int, tag: str):
    from wheelcal.batch.pipeline import load_pipeline
    from wheelcal.batch.runner import run_batch

    out = root / f"out_{tag}"
    toml = root / f"{tag}.toml"
    toml.write_text(
        f'[pipeline]\nname = "imu"\noutput = "{out}"\n[inputs]\nglobs = ["{inputs}/*.mcap"]\n'
        f"[run]\nrerun = false\n[executor]\nworkers = {workers}\n"
    )

    def run() -> None:
        shutil.rmtree(out, ignore_errors=True)
        before = _cpu_s()
        run_batch(load_pipeline(toml))
        CPU_S.setdefault(tag, []).append(_cpu_s() - before)

    return run, out


#: CPU seconds of each batch run, by tag (this process and its finished workers).
CPU_S: dict[str, list[float]] = {}


def _cpu_s() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    workers = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + workers.ru_utime + workers.ru_stime


def main() -> int:
    """Time and print."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args()

    import wheelcal.calibration.sensor_json as sensor_json
    from wheelcal.calibration.gyro_json import gyro_block

    root = Path(tempfile.mkdtemp(prefix="bench_gyro_matrix_"))
    try:
        inputs = root / "in"
        _recordings(inputs)
        with_gyro, out = _batch(root, inputs, args.workers, "gyro")
        plain, _ = _batch(root, inputs, args.workers, "plain")

        def without_gyro() -> None:
            sensor_json.gyro_block = lambda calibrations: {}  # the baseline: no gyro block
            try:
                plain()
            finally:
                sensor_json.gyro_block = gyro_block

        rounds = interleaved_times(
            {"batch": with_gyro, "without the pooled gyro fit": without_gyro}, args.rounds
        )
        docs = [json.loads(p.read_text()) for p in sorted(out.glob("s*.calibration.json"))]
        pooled = times(lambda: gyro_block(docs), 20)
        sensor = json.loads((out / "sensors" / "imu.calibration.json").read_text())
        assert sensor["gyro"]["undetermined"] == [], sensor["gyro"]["undetermined"]
        for name, ts in rounds.items():
            print(f"{name:<30} {fmt(ts)}")
        print(f"{'pooled gyro fit alone':<30} {fmt(pooled)}  ({len(docs)} sessions)")
        ratios = [
            a / b
            for a, b in zip(rounds["batch"], rounds["without the pooled gyro fit"], strict=True)
        ]
        share = statistics.median(pooled) / statistics.median(rounds["batch"])
        cpu_gyro, cpu_plain = CPU_S["gyro"][1:], CPU_S["plain"][1:]  # after the warm-up
        cpu_ratio = statistics.median(a / b for a, b in zip(cpu_gyro, cpu_plain, strict=True))
        print(
            f"CPU s per batch: {statistics.median(cpu_gyro):.2f} with the pooled gyro fit, "
            f"{statistics.median(cpu_plain):.2f} without; median ratio {cpu_ratio:.3f}"
        )
        print(
            f"batch / batch without it: median of the rounds' ratios {statistics.median(ratios):.3f}"
            f" (target ≤ 1.05); the pooled fit alone is {100 * share:.2f} % of the batch"
        )
    finally:
        shutil.rmtree(root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
