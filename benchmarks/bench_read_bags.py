"""Reading speed of robot logs against the MCAP path, on the same samples, in one process.

Writes one 18,000-sample recording (table II bench, 200 Hz, one sample per
``sensor_msgs/Imu`` message) as

* the contract's ROS 2 MCAP (zstd chunks, every CRC) — today's path, the baseline;
* a rosbag2 ``.db3`` (SQLite storage), by ``rosbags.rosbag2.Writer``;
* a ROS 1 ``.bag`` (lz4 chunks, and bz2), by ``rosbags.rosbag1.Writer``;
* a ROS 1-encoded MCAP (what ``mcap convert`` makes of a bag), by ``mcap``'s Writer;

and times ``wheelcal.io.read_recording`` on each (the whole reader: scan, decode,
sample checks), interleaved round by round, with the allocator tuned as the CLI
tunes it.  Also ``rosbags``' own readers (messages out, no decoding) for
scale.  Prints samples/s and the median of the per-round ratios to the MCAP
path; process CPU time (one core), ``--wall`` for the wall clock.
Run: ``PYTHONPATH=src:tests python benchmarks/bench_read_bags.py [--repeat 15]``
(needs the test extra: rosbags).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _timing import interleaved_times
from bench_read import table2_recording

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from robot_logs import imu_messages, write_bag, write_db3, write_ros1_mcap
from wheelcal.io import read_recording, write_recording
from wheelcal.runtime import tune_allocator

SAMPLES = 18_000


def rosbags_raw(path: Path):
    """rosbags' own reader: every message's bytes (no decoding) — for scale."""
    if path.suffix == ".bag":
        from rosbags.rosbag1 import Reader
    else:
        from rosbags.rosbag2 import Reader
    with Reader(path) as reader:
        return [raw for _, _, raw in reader.messages()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--wall", action="store_true", help="wall clock instead of CPU time")
    args = parser.parse_args()
    tune_allocator()
    clock = time.perf_counter if args.wall else time.process_time
    recording = table2_recording(SAMPLES)
    time_ns = recording.epoch_unix_ns + np.rint(recording.time_s * 1e9).astype(np.int64)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        files = {"MCAP, ROS 2 (baseline)": tmp / "imu.mcap"}
        write_recording(recording, files["MCAP, ROS 2 (baseline)"])
        cdr = imu_messages(time_ns, recording.accel_mps2)
        ros1 = imu_messages(time_ns, recording.accel_mps2, ros1=True)
        files["rosbag2 .db3 (SQLite)"] = write_db3(tmp / "bag2", time_ns, cdr)
        files["ROS 1 .bag, lz4 chunks"] = write_bag(tmp / "lz4.bag", time_ns, ros1)
        files["ROS 1 .bag, bz2 chunks"] = write_bag(
            tmp / "bz2.bag", time_ns, ros1, compression="bz2"
        )
        files["MCAP, ROS 1 encoding"] = write_ros1_mcap(tmp / "ros1.mcap", time_ns, ros1)
        for path in files.values():  # the same samples from every file
            assert np.array_equal(read_recording(path).accel_mps2, recording.accel_mps2)
        fns = {label: (lambda p=path: read_recording(p)) for label, path in files.items()}
        fns["rosbags Reader, .db3 (bytes only)"] = lambda: rosbags_raw(
            files["rosbag2 .db3 (SQLite)"]
        )
        fns["rosbags Reader, .bag lz4 (bytes only)"] = lambda: rosbags_raw(
            files["ROS 1 .bag, lz4 chunks"]
        )
        ts = interleaved_times(fns, args.repeat, clock=clock)
    what = "wall clock" if args.wall else "CPU time, one core"
    print(f"{SAMPLES} samples per file, {args.repeat} interleaved rounds, {what}")
    print(
        f"{'read_recording of':38s} {'median':>10s} {'samples/s':>12s} {'÷ MCAP (per round)':>19s}"
    )
    baseline = ts["MCAP, ROS 2 (baseline)"]
    for label, t in ts.items():
        ratio = statistics.median(a / b for a, b in zip(t, baseline, strict=True))
        median = statistics.median(t)
        print(f"{label:38s} {1e3 * median:8.1f} ms {SAMPLES / median:12,.0f} {ratio:18.2f}x")


if __name__ == "__main__":
    main()
