"""Read throughput of wheelcal's MCAP reader versus the plain mcap / mcap_ros2 decoders.

Generates 18,000-sample recordings (table II bench, 200 Hz) in a temporary
directory — ROS 2 Imu (one sample per message), JSON AccelBatch with one
sample per message and batched — and times, in this one process:

* ``wheelcal.io.read_recording`` (every CRC verified, samples checked);
* the plain path: ``mcap.reader.make_reader(..., validate_crcs=True)`` with
  ``mcap_ros2.decoder.DecoderFactory`` (``iter_decoded_messages``) for ROS 2,
  ``iter_messages`` + ``json.loads`` per message for JSON, collected into the
  same numpy arrays.

Best of ``--repeat`` runs of this process's CPU time (``time.process_time``:
every reader here runs on one thread — Arrow's JSON reader is asked for
``use_threads=False`` — so this is the one-core figure, and it is not
inflated by other load on the machine); ``--wall`` uses the wall clock.
``--ref REV`` also extracts ``src/wheelcal`` at that git revision (as
``wheelcal_ref``, see ``bench_versus.py``) and times its ``read_recording``
against this tree's, interleaved round by round in this process, printing
both rates and the median of the per-round ratios.
The allocator is tuned as the CLI and the batch workers tune it
(``wheelcal.runtime.tune_allocator``: large temporaries stay in the heap
instead of being mapped and faulted in afresh); ``--untuned`` times glibc's
defaults (the setting is process-wide, so one run measures one of the two).
Run: ``python benchmarks/bench_read.py [--compression zstd|lz4|none] [--ref main] [--untuned]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from _timing import interleaved_times
from bench_versus import reference_code
from wheelcal.io import read_recording, write_recording
from wheelcal.runtime import tune_allocator
from wheelcal.simulate import Scenario, simulate, table2

SAMPLES = 18_000


def plain_ros2(path: Path) -> tuple[np.ndarray, np.ndarray]:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    stamps, accel = [], []
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True, decoder_factories=[DecoderFactory()])
        for _, _, _, msg in reader.iter_decoded_messages():
            stamp = msg.header.stamp
            stamps.append(stamp.sec * 1_000_000_000 + stamp.nanosec)
            a = msg.linear_acceleration
            accel.append((a.x, a.y, a.z))
    return np.array(stamps, dtype=np.int64), np.array(accel)


def plain_json(path: Path) -> tuple[np.ndarray, np.ndarray]:
    from mcap.reader import make_reader

    stamps, accel = [], []
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        for _, _, message in reader.iter_messages():
            batch = json.loads(message.data)
            stamps.extend(batch["timestamps_ns"])
            accel.extend(batch["accel"])
    return np.array(stamps, dtype=np.int64), np.array(accel)


def table2_recording(samples: int = SAMPLES):
    """The benchmarks' recording: a table II bench at 200 Hz, ``samples`` samples, fixed seeds."""
    base = table2(rng=np.random.default_rng(1))
    scenario = Scenario(
        truth=base.truth, duration_s=(samples - 1) / base.rate_hz, rate_hz=base.rate_hz
    )
    recording = simulate(scenario, np.random.default_rng(2)).recording
    assert recording.samples == samples
    return recording


def best_time(fn, repeat: int, clock) -> float:
    fn()  # warm-up (imports, caches)
    times = []
    for _ in range(repeat):
        start = clock()
        fn()
        times.append(clock() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--compression", default="zstd", choices=["zstd", "lz4", "none"])
    parser.add_argument(
        "--wall",
        action="store_true",
        help="time with the wall clock instead of this process's CPU time",
    )
    parser.add_argument(
        "--ref", help="git revision whose reader to time against this tree's, e.g. main"
    )
    parser.add_argument(
        "--untuned", action="store_true", help="glibc's allocator defaults (the CLI tunes them)"
    )
    args = parser.parse_args()
    if not args.untuned:
        tune_allocator()
    clock = time.perf_counter if args.wall else time.process_time

    recording = table2_recording()
    variants = [
        ("ROS 2 Imu, 1 sample/msg", "ros2", 1, plain_ros2),
        ("JSON, 1 sample/msg", "json", 1, plain_json),
        ("JSON, 10 samples/msg", "json", 10, plain_json),
        ("JSON, 50 samples/msg", "json", 50, plain_json),
    ]
    what = "wall-clock" if args.wall else "CPU (one core: all readers are single-threaded)"
    allocator = "glibc's defaults" if args.untuned else "allocator tuned as the CLI tunes it"
    print(f"{SAMPLES} samples per file, {args.compression} chunks, best of {args.repeat}, {what}")
    print(allocator)
    print(f"{'file':26s} {'wheelcal':>14s} {'plain decoder':>14s} {'ratio':>7s}")
    with tempfile.TemporaryDirectory() as tmp:
        for label, encoding, batch, plain in variants:
            path = Path(tmp) / f"{encoding}_{batch}.mcap"
            write_recording(
                recording, path, encoding=encoding, batch_size=batch, compression=args.compression
            )
            ours = read_recording(path)
            stamps, accel = plain(path)
            assert np.array_equal(ours.accel_mps2, accel), "readers disagree"
            assert np.array_equal(ours.epoch_unix_ns + np.rint(ours.time_s * 1e9), stamps)
            t_ours = best_time(lambda p=path: read_recording(p), args.repeat, clock)
            t_plain = best_time(lambda p=path, f=plain: f(p), args.repeat, clock)
            print(
                f"{label:26s} {SAMPLES / t_ours:10,.0f} /s {SAMPLES / t_plain:10,.0f} /s "
                f"{t_plain / t_ours:6.1f}x"
            )
        if args.ref:
            with reference_code(args.ref):
                versus_ref(args.ref, Path(tmp), variants, args.repeat, clock)


def versus_ref(ref: str, tmp: Path, variants, repeat: int, clock) -> None:
    """This tree's reader against ``ref``'s on the same files, interleaved round by round."""
    from wheelcal_ref.io import read_recording as read_ref

    print(f"\nversus {ref}, interleaved, median of {repeat} rounds (ratio: per-round median)")
    print(f"{'file':26s} {'ref':>14s} {'now':>14s} {'ref/now':>8s}")
    for label, encoding, batch, _ in variants:
        path = tmp / f"{encoding}_{batch}.mcap"
        assert np.array_equal(read_ref(path).accel_mps2, read_recording(path).accel_mps2)
        ts = interleaved_times(
            {"ref": lambda p=path: read_ref(p), "now": lambda p=path: read_recording(p)},
            repeat,
            clock=clock,
        )
        ratio = statistics.median(a / b for a, b in zip(ts["ref"], ts["now"], strict=True))
        print(
            f"{label:26s} {SAMPLES / statistics.median(ts['ref']):10,.0f} /s "
            f"{SAMPLES / statistics.median(ts['now']):10,.0f} /s {ratio:7.2f}x"
        )


if __name__ == "__main__":
    main()
