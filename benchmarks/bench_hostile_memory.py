"""Peak memory and time of every hostile (non-CSV) input of issue 40, beside a sound one.

Builds, in a temporary directory (or ``--dir``), the hostile files of issue 40
and, for each family, a sound file of the same kind as the baseline:

* ROS 1 ``.bag``: a bz2 chunk of 3000 MiB of zeros (concatenated streams, ~120 KB of
  file) claiming its true size, the same claiming 100× its compressed size, an lz4
  frame of 3 GiB of zeros (~12 MB);
* rosbag2 with per-message zstd: one message of 3 GiB of zeros (its frame states the
  size), the same without a stated size, a 26-byte frame declaring 6 GB;
* MCAP (already bounded before issue 40, for comparison): a zstd chunk of 512 MiB of
  zeros with a true size and CRC;
* ``convert``, ``export``, ``batch`` given a FIFO with no writer or ``/dev/zero``;

and runs each command in a fresh subprocess (``wheelcal calibrate FILE`` for the
recordings), started by a tiny launcher that reports the child's peak resident set
size (``ru_maxrss`` of ``RUSAGE_CHILDREN``) and a 60 s timeout.  Prints one
row per case — exit status, peak RSS, wall time, the first words of the error —,
the ratio of each hostile case's peak to its family's baseline in the same run,
and whether every hostile case stayed within 1 GiB and 60 s (issue 40's bound).

Run: ``PYTHONPATH=src:tests python benchmarks/bench_hostile_memory.py [--dir DIR]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

MIB = 1 << 20
LIMIT_RSS_MIB = 1024
LIMIT_S = 60.0

_LAUNCH = """
import json, resource, subprocess, sys, time
t0 = time.perf_counter()
try:
    run = subprocess.run(sys.argv[1:], capture_output=True, text=True, timeout=float(sys.argv[0]))
    rc, err = run.returncode, run.stderr
except subprocess.TimeoutExpired as exc:
    rc, err = "timeout", (exc.stderr or b"").decode(errors="replace") if exc.stderr else ""
wall = time.perf_counter() - t0
print(json.dumps([resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, rc, wall, err]))
"""


def _bz2_zeros(mib: int) -> bytes:
    import bz2

    return bz2.compress(bytes(MIB)) * mib


def _lz4_zeros(size: int) -> bytes:
    import lz4.frame

    comp = lz4.frame.LZ4FrameCompressor()
    block = bytes(MIB)
    return comp.begin() + b"".join(comp.compress(block) for _ in range(size // MIB)) + comp.flush()


def _zstd_zeros(size: int, content_size: bool) -> bytes:
    import zstandard

    comp = zstandard.ZstdCompressor(write_content_size=content_size).compressobj(size=size)
    block = bytes(MIB)
    return b"".join(comp.compress(block) for _ in range(size // MIB)) + comp.flush()


def _zstd_frame_declaring(size: int) -> bytes:
    block = ((16 << 3) | 1).to_bytes(3, "little")
    return b"\x28\xb5\x2f\xfd" + bytes([0xE0]) + size.to_bytes(8, "little") + block + bytes(16)


def _record(op: int, content: bytes) -> bytes:
    return bytes([op]) + len(content).to_bytes(8, "little") + content


def _string(text: str) -> bytes:
    return len(text.encode()).to_bytes(4, "little") + text.encode()


def _mcap_bomb(data: bytes, size: int) -> bytes:
    """An MCAP of one zstd chunk claiming ``size`` bytes, with the true CRC of that many zeros."""
    import zlib

    from wheelcal.io.mcap_scan import MAGIC

    crc, block = 0, bytes(MIB)
    for _ in range(size // MIB):
        crc = zlib.crc32(block, crc)
    chunk = _record(
        0x06,
        bytes(16)
        + size.to_bytes(8, "little")
        + crc.to_bytes(4, "little")
        + _string("zstd")
        + len(data).to_bytes(8, "little")
        + data,
    )
    head = _record(0x01, _string("") + _string("hostile"))
    tail = _record(0x0F, bytes(4)) + _record(0x02, bytes(20))
    return MAGIC + head + chunk + tail + MAGIC


def build(d: Path) -> dict[str, tuple[str, list[str], Path | None]]:
    """case → (family, command, file), building the files that are not there yet."""
    from robot_logs import imu_messages, raw_bag, write_db3
    from wheelcal.cli.main import main
    from wheelcal.io import write_recording
    from wheelcal.simulate import table2
    from wheelcal.simulate.session import simulate_session

    d.mkdir(parents=True, exist_ok=True)
    out = str(d / "out")
    rec = simulate_session(table2(rng=np.random.default_rng(8)), np.random.default_rng(9)).recording
    time_ns = rec.epoch_unix_ns + np.rint(rec.time_s * 1e9).astype(np.int64)
    ros1 = imu_messages(time_ns, rec.accel_mps2, ros1=True)
    short_ns, short = time_ns[:2000], ros1[:2000]

    def once(path: Path, make) -> Path:
        if not path.exists():
            make(path)
        return path

    def cal(path: Path) -> list[str]:
        return ["calibrate", str(path), "--out", out, "--radius", "0.28", "--quiet", "--force"]

    cases = {}
    mcap = once(d / "sound.mcap", lambda p: write_recording(rec, p))
    cases["MCAP: sound recording (baseline)"] = ("MCAP", cal(mcap), mcap)
    bomb = once(
        d / "bomb.mcap",
        lambda p: p.write_bytes(_mcap_bomb(_zstd_zeros(512 * MIB, True), 512 * MIB)),
    )
    cases["MCAP: zstd chunk of 512 MiB zeros, true size and CRC"] = ("MCAP", cal(bomb), bomb)

    bag = once(d / "sound.bag", lambda p: p.write_bytes(raw_bag(time_ns, ros1, compression="bz2")))
    cases["ROS 1 bag: sound, bz2 chunk (baseline)"] = ("bag", cal(bag), bag)
    zeros = _bz2_zeros(3000)
    for name, claim in (("true", 3000 * MIB), ("100x", 100 * len(zeros))):
        path = once(
            d / f"bz2_{name}.bag",
            lambda p, claim=claim: p.write_bytes(
                raw_bag(short_ns, short, compression="bz2", chunk_data=zeros, chunk_size=claim)
            ),
        )
        label = "its true size" if name == "true" else "100× its compressed size"
        cases[f"ROS 1 bag: bz2 chunk of 3000 MiB zeros claiming {label}"] = ("bag", cal(path), path)
    lz4 = once(
        d / "lz4.bag",
        lambda p: p.write_bytes(
            raw_bag(
                short_ns,
                short,
                compression="lz4",
                chunk_data=_lz4_zeros(3072 * MIB),
                chunk_size=3072 * MIB,
            )
        ),
    )
    cases["ROS 1 bag: lz4 frame of 3 GiB zeros"] = ("bag", cal(lz4), lz4)

    ros2 = imu_messages(time_ns, rec.accel_mps2)
    sound2 = d / "sound_rosbag2"
    if not sound2.exists():
        write_db3(sound2, time_ns, ros2, zstd_messages=True)
    cases["rosbag2: sound, per-message zstd (baseline)"] = ("rosbag2", cal(sound2), sound2)
    for name, make in (
        ("sized", lambda: _zstd_zeros(3072 * MIB, True)),
        ("unsized", lambda: _zstd_zeros(3072 * MIB, False)),
        ("six_gb", lambda: _zstd_frame_declaring(6_000_000_000)),
    ):
        folder = d / f"rosbag2_{name}"
        if not folder.exists():
            db3 = write_db3(folder, short_ns, ros2[:2000], zstd_messages=True)
            with sqlite3.connect(db3) as db:
                db.execute(
                    "UPDATE messages SET data = ? WHERE id = (SELECT MIN(id) FROM messages)",
                    (make(),),
                )
        label = {
            "sized": "one message of 3 GiB zeros (size in its frame)",
            "unsized": "one message of 3 GiB zeros (no size in its frame)",
            "six_gb": "a 26-byte frame declaring 6 GB",
        }[name]
        cases[f"rosbag2: {label}"] = ("rosbag2", cal(folder), folder)

    csv = d / "sound.csv"
    if not csv.exists():
        rows = ["time,ax,ay,az"] + [
            f"{t:.4f},{a[0]:.5f},{a[1]:.5f},{a[2]:.5f}"
            for t, a in zip(rec.time_s, rec.accel_mps2, strict=True)
        ]
        csv.write_text("\n".join(rows) + "\n")
    conv = ["--accel-unit", "m/s^2", "--radius", "0.28", "--force"]
    cases["convert: sound CSV, 18,000 rows (baseline)"] = (
        "convert",
        ["convert", str(csv), str(d / "sound_csv.mcap"), *conv],
        csv,
    )
    calibration = d / "out" / "sound.calibration.json"
    if not calibration.exists():
        assert main(cal(mcap)) == 0
    cases["export: sound calibration (baseline)"] = (
        "export",
        ["export", str(calibration), "--format", "yaml"],
        calibration,
    )
    pipeline = d / "sound.toml"
    pipeline.write_text(
        f'[pipeline]\nname = "b"\noutput = "{d / "batch_out"}"\n'
        f'[inputs]\nglobs = ["{mcap}"]\n[defaults]\nradius_m = 0.28\n'
    )
    cases["batch: sound one-session pipeline (baseline)"] = (
        "batch",
        ["batch", str(pipeline), "--force"],
        pipeline,
    )
    fifo = d / "fifo"
    if not fifo.exists():
        os.mkfifo(fifo)
    for given, what in ((str(fifo), "a FIFO with no writer"), ("/dev/zero", "/dev/zero")):
        cases[f"convert: {what}"] = ("convert", ["convert", given, str(d / "x.mcap"), *conv], None)
        cases[f"export: {what}"] = ("export", ["export", given, "--format", "yaml"], None)
        cases[f"batch: {what}"] = ("batch", ["batch", given], None)
    return cases


def measure(command: list[str]) -> tuple[float, object, float, str]:
    """(peak RSS MiB, exit status or "timeout", wall s, stderr) of one fresh CLI process."""
    child = [sys.executable, "-m", "wheelcal.cli.main", *command]
    launcher = [sys.executable, "-c", _LAUNCH.replace("float(sys.argv[0])", str(LIMIT_S))]
    done = subprocess.run([*launcher, *child], capture_output=True, text=True, check=True)
    rss_kib, status, wall, err = json.loads(done.stdout.strip().splitlines()[-1])
    return rss_kib / 1024, status, wall, err


def _first_words(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    failed = [line for line in lines if line.startswith("FAILED")]
    text = (failed or lines or [""])[-1]
    for marker in ("error: ", "FAILED  "):
        if marker in text:
            text = text.split(marker, 1)[1]
    return (text[:110] + "…") if len(text) > 110 else text


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dir", type=Path, help="where the files are built (reused)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = args.dir or Path(tmp)
        t0 = time.perf_counter()
        cases = build(d)
        print(f"built {len(cases)} cases in {d} ({time.perf_counter() - t0:.0f} s)\n")
        print("| case | file | exit | peak RSS (MiB) | × baseline | wall (s) | says |")
        print("|---|---:|---:|---:|---:|---:|---|")
        baseline: dict[str, float] = {}
        worst_rss, worst_s, over = 0.0, 0.0, []
        for name, (family, command, path) in cases.items():
            rss, status, wall, err = measure(command)
            size = _size(path)
            is_base = "(baseline)" in name
            if is_base:
                baseline[family] = rss
            ratio = "1" if is_base else f"{rss / baseline[family]:.2f}"
            print(
                f"| {name} | {size} | {status} | {rss:.0f} | {ratio} | {wall:.2f} | "
                f"{_first_words(err) if not is_base else ''} |"
            )
            if not is_base:
                worst_rss, worst_s = max(worst_rss, rss), max(worst_s, wall)
                if rss > LIMIT_RSS_MIB or wall > LIMIT_S or status == "timeout":
                    over.append(name)
        print(
            f"\nhostile cases: worst peak RSS {worst_rss:.0f} MiB (limit {LIMIT_RSS_MIB}), "
            f"worst wall {worst_s:.1f} s (limit {LIMIT_S:g}); over a limit: {over or 'none'}"
        )
        return 1 if over else 0


def _size(path: Path | None) -> str:
    if path is None or not path.exists():
        return "–"
    if path.is_dir():
        total = sum(p.stat().st_size for p in path.iterdir() if p.is_file())
    else:
        total = path.stat().st_size
    return f"{total / 1e6:.2f} MB" if total >= 1e5 else f"{total / 1e3:.1f} kB"


if __name__ == "__main__":
    sys.exit(main())
